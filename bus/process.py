"""Helpers every node process shares: stop on SIGINT/SIGTERM, sim-time/wall-time pacing, and a lower
CPU priority for the processes off a lockstep run's critical path."""

from __future__ import annotations

import os
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


def lower_cpu_priority(niceness: int) -> int:
    """Run this process at ``niceness`` (1-19; 0 asks for nothing): its calling thread, and so every
    thread it starts afterwards (call it before the zenoh session opens). Raising one's own niceness
    needs no privilege. Linux shares the cores between sessions (autogroups,
    ``kernel.sched_autogroup_enabled``) before it weighs nice values, so a nice value orders only the
    processes of one session: `swarm up` keeps the processes it starts in the session it runs in
    (launch.children.own_process_group), and the session's own nice value is left alone, so that a
    swarm is never starved beside the other sessions of a shared machine. Returns the niceness
    applied (0: none, or not on this platform)."""
    if niceness <= 0 or not hasattr(os, "setpriority"):
        return 0
    try:
        os.setpriority(os.PRIO_PROCESS, 0, max(os.getpriority(os.PRIO_PROCESS, 0), niceness))
    except OSError:
        return 0
    return niceness


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
