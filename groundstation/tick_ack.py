"""When a lockstep ground station acknowledges the world's tick (groundstation.node).

The world sends tick k+1 only once the ground station has acknowledged tick k, so what the ground
station has scored and put on disk by then is all a crash of it can keep. It acknowledges tick k
once its mailbox is drained (the clock's lane is served first), a paced live view is not ahead of
the wall clock, and the previous tick is in: tick k-1's truth and the estimates up to its stamp of
every vehicle that acknowledged it (``ClockTick.running``: each published them before) and kept up
so far. Zenoh keeps the order of a key, not across keys: tick k can come before frames published
ahead of it, and a ground station killed then lost them as well. A vehicle whose estimates stopped
short of the tick acknowledged before (restarted, or without an estimate yet) is not waited for,
and the wait is at most ``ACK_HOLD_S``.
"""

from __future__ import annotations

import logging
import time

log = logging.getLogger("swarmloc.groundstation")
ACK_HOLD_S = 1.0  # the longest a tick's acknowledgement waits for the tick before's estimates


class TickAck:
    """The tick waiting for its acknowledgement (``due``, None: none), when it came, the vehicles
    that acknowledged the tick before it, and the estimates every vehicle that keeps up had sent by
    the last acknowledgement."""

    def __init__(self) -> None:
        self.due: int | None = None
        self._came_s = 0.0  # monotonic
        self._running: set[int] = set()
        self._kept_up_us = -1
        self._due_us = -1  # the last ODOMETRY stamp the waiting tick's previous one covers

    def came(self, tick: int, running: tuple[int, ...]) -> None:
        self.due, self._came_s, self._running = tick, time.monotonic(), set(running)

    def previous_tick_in(self, published_us: int, period_us: int, streams: dict[int, int], truth_us: int) -> bool:
        """Whether tick ``due``'s previous one is in (module docstring): ``published_us``, that
        tick's stamp (< 0: none); ``period_us``, the vehicles' ODOMETRY period; ``streams``, each
        vehicle's newest estimate stamp; ``truth_us``, the newest truth stamp."""
        if published_us < 0:
            return True
        self._due_us = published_us - published_us % period_us
        behind = sorted(vid for vid in self._running if self._kept_up_us <= streams.get(vid, -2) < self._due_us)
        if not behind and truth_us >= published_us:
            return True
        if time.monotonic() - self._came_s <= ACK_HOLD_S:
            return False
        missing = f"the estimates of vehicles {behind}" if behind else "the truth"
        log.warning("tick %d acknowledged %g s after it came without %s", self.due, ACK_HOLD_S, missing)
        return True

    def sent(self) -> int:
        """The acknowledgement of tick ``due`` goes out: its number."""
        tick, self.due = self.due, None
        self._kept_up_us = max(self._kept_up_us, self._due_us)
        return tick


def paced_ahead(live_speed: float | None, wall_start: float | None, sim_time_us: int) -> bool:
    """With a paced live view (``view.live_speed``): whether the run is ahead of that many times
    real time (``wall_start``: perf_counter at the run's start), so the tick's acknowledgement
    waits (the ground station's loop comes back within 0.2 s)."""
    if not (live_speed and wall_start):
        return False
    return time.perf_counter() - wall_start < sim_time_us * 1e-6 / live_speed


def watermark_us(published_us: int, streams_us: dict[int, int], held_us: int | None) -> int:
    """Lockstep: estimates up to the returned stamp can be scored in (time, vehicle) order. Every
    estimate up to ``published_us`` is published and its truth in; each vehicle the world's tick
    waited for has published past its ``streams_us`` entry (its own stream's progress: zenoh keeps
    order within a key, not across keys; a vehicle that joined during the run, a restart, counts as
    past the tick before the one that first listed it, since it publishes only what comes after, so
    the others' are not held for it until its first frame comes); and no delay fault holds an
    estimate stamped ``held_us`` or later. The vehicles counted are those the tick waited for, not
    those whose liveliness this process has heard: a token is another key, and when it arrives must
    not decide the order in which estimates are scored."""
    marks = [published_us, *streams_us.values()]
    return min(marks) if held_us is None else min(*marks, held_us - 1)
