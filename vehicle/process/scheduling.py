"""The realtime estimator loop's scheduling class. On a 2-core machine running 20 vehicle processes,
the world, the ground station and the router, the kernel's fair scheduler lets a vehicle that wakes
for its deadline wait behind whichever process holds the core, for several milliseconds at the 99th
percentile. An embedded estimator runs its loop as a real-time thread; so does this one when the
kernel allows it: SCHED_FIFO at ``vehicle.realtime.priority`` (root, CAP_SYS_NICE, or an RLIMIT_RTPRIO
that covers the priority), and the fair scheduler otherwise. The loop sleeps or blocks between
cycles, and the kernel's real-time throttling (95 % of each second by default) bounds what a
runaway loop could take."""

from __future__ import annotations

import logging
import os

log = logging.getLogger("swarmloc.vehicle")


def ask_for_realtime_priority(priority: int) -> int:
    """Put the calling thread under SCHED_FIFO at ``priority`` (1-99; 0 asks for nothing). Returns the
    priority granted, 0 when the thread stays under the fair scheduler (not asked, not allowed, or no
    such scheduling class on this platform). Threads the caller starts afterwards inherit it."""
    if priority <= 0:
        return 0
    fifo = getattr(os, "SCHED_FIFO", None)
    if fifo is None or not hasattr(os, "sched_setscheduler"):
        log.info("no SCHED_FIFO on this platform; the loop runs under the fair scheduler")
        return 0
    try:
        os.sched_setscheduler(0, fifo, os.sched_param(priority))
    except OSError as exc:  # EPERM without the privilege; EINVAL outside the platform's range
        log.info(
            "SCHED_FIFO priority %d refused (%s); the loop runs under the fair scheduler "
            "(needs root, CAP_SYS_NICE or `ulimit -r` >= %d)",
            priority,
            exc.strerror or exc,
            priority,
        )
        return 0
    return priority
