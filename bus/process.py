"""Helpers every node process shares: stop on SIGINT/SIGTERM, and sim-time/wall-time pacing."""

from __future__ import annotations

import signal
import threading
import time


def die_with_parent(sig: int = signal.SIGTERM) -> None:
    """Ask Linux to send ``sig`` to this process when the thread that started it ends (a campaign's
    run when its worker is lost; a swarm's process when its forkserver ends): PR_SET_PDEATHSIG. A
    parent already gone by now is treated the same. Elsewhere (not Linux) nothing is set."""
    import ctypes
    import os

    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(sig), 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() == 1:  # the parent died before the request took effect
        os.kill(os.getpid(), sig)


def stop_on_signals() -> threading.Event:
    """An Event set by SIGINT or SIGTERM, so loops end cleanly and sessions close."""
    stop = threading.Event()

    def handler(signum: int, frame: object) -> None:
        stop.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return stop


class Pacer:
    """Maps sim time (us) to wall time (ns) for realtime runs: wall = wall0 + (sim - sim0) / speed."""

    def __init__(self, *, sim0_us: int, wall0_ns: int, speed: float) -> None:
        self.sim0_us, self.wall0_ns, self.speed = sim0_us, wall0_ns, speed

    def wall_ns(self, sim_us: int) -> int:
        return self.wall0_ns + int((sim_us - self.sim0_us) * 1000 / self.speed)

    def seconds_until(self, sim_us: int) -> float:
        return (self.wall_ns(sim_us) - time.time_ns()) * 1e-9
