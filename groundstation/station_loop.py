"""The ground station's loop: handle mailbox items until the world ends the run (or a stop signal,
or the world is gone), let stragglers land, then write the summary.

Nobody waits silently: a world that never joins within ``start_timeout_s`` ends the run as
``no-world``; one whose liveliness token is gone for ``gone_timeout_s`` without ending the run ends it
as ``world-lost``. Both are errors (the command exits non-zero).
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path

from bus.config import SwarmConfig
from bus.errors import SwarmlocError
from bus.session import Bus
from groundstation.mavlink_out import MavlinkForwarder
from groundstation.node import GroundStation

FINAL_WAIT_S = 30.0
log = logging.getLogger("swarmloc.groundstation")


class WorldGone(SwarmlocError):
    """The world never joined, or left without ending the run; the summary says so."""


def run_groundstation(
    bus: Bus,
    config: SwarmConfig,
    run_dir: Path,
    stop: threading.Event,
    on_progress=None,
    *,
    master_key: bytes | None = None,
    forwarder: MavlinkForwarder | None = None,
) -> dict:
    """Score until the world ends the run (or ``stop`` is set); returns the summary. Raises WorldGone
    (after writing the summary) when the world never came or vanished."""
    gs = GroundStation(bus, config, run_dir, master_key=master_key, forwarder=forwarder)
    if on_progress is not None:
        gs.on_progress = on_progress
    gs.publish_plan()
    watch = _WorldWatch(gs, config)
    while gs.ended is None and not stop.is_set() and watch.status is None:
        item = gs.mailbox.get(0.2)
        if item is None:
            gs.run.maybe_flush()
        else:
            gs.handle(item)
        gs.ack_if_drained()
        watch.check()
    if gs.ended is not None:
        _await_final_data(gs, FINAL_WAIT_S)
    status = gs.ended.status if gs.ended is not None else (watch.status or "interrupted")
    summary = gs.finish(status)
    if watch.status is not None:
        raise WorldGone(watch.explain())
    return summary


class _WorldWatch:
    """Decides when the world is gone for good."""

    def __init__(self, gs: GroundStation, config: SwarmConfig) -> None:
        self.gs, self.clock = gs, config.clock
        self.start = time.monotonic()
        self.gone_since: float | None = None
        self.status: str | None = None

    def check(self) -> None:
        now, gs = time.monotonic(), self.gs
        if not gs.presence.world_seen:
            if now - self.start > self.clock.start_timeout_s:
                self.status = "no-world"
            return
        if gs.presence.world_alive:
            self.gone_since = None
        elif self.gone_since is None:
            self.gone_since = now
        elif now - self.gone_since > self.clock.gone_timeout_s:
            self.status = "world-lost"

    def explain(self) -> str:
        if self.status == "no-world":
            return f"the world did not join within {self.clock.start_timeout_s:g} s; run ended as no-world"
        return f"the world left without ending the run ({self.clock.gone_timeout_s:g} s ago); run ended as world-lost"


def _await_final_data(gs: GroundStation, timeout_s: float) -> None:
    """Keys are not ordered among each other, so the end of the run can overtake the last frames,
    statuses and truth. Every vehicle the world names as completed sent its frames and final status
    before its final ack, and the world sent the truth of every tick up to the end's before the end:
    wait until they are in (a deadline only guards against a bus that lost them; it is logged). A
    ground station behind the vehicles in priority (lockstep's background niceness) had the end
    before the last tick's truth in 2 of 21 runs of three swarms at once."""
    end = gs.ended
    deadline = time.monotonic() + timeout_s
    period_us = round(1e6 / gs.config.vehicle.mavlink_rate_hz)
    last_odometry_us = end.stamp_us - end.stamp_us % period_us

    def missing() -> list[int]:
        return [
            vid
            for vid in end.completed
            if gs.intake.stream_stamp_us.get(vid, -1) < last_odometry_us
            or vid not in gs.reports.statuses
            or not gs.reports.statuses[vid].final
        ]

    def waiting() -> bool:
        return bool(missing()) or gs.truth_tick < end.tick

    while waiting() and time.monotonic() < deadline:
        item = gs.mailbox.get(0.1)
        if item is not None:
            gs.handle(item)
    while (item := gs.mailbox.get_nowait()) is not None:  # what is already here
        gs.handle(item)
    if missing():
        log.warning("final data of vehicles %s did not arrive within %g s", missing(), timeout_s)
    if gs.truth_tick < end.tick:
        log.warning("truth of ticks %d..%d did not arrive within %g s", gs.truth_tick + 1, end.tick, timeout_s)
