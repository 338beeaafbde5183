"""A lockstep swarm on a machine shared with other CPU-bound work: the 5-vehicle demo alone and beside
two busy loops, each loop a session of its own (another user's jobs), interleaved in one sitting,
medians of ``ROUNDS``. In lockstep the world and the ground station run at niceness 19 so that the
vehicles' cycles get the cores first; that must order the swarm's own processes only, never leave
the swarm waiting behind the other sessions (launch.children.own_process_group)."""

from __future__ import annotations

import contextlib
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

from bench.bench_speed import DEMO, timed
from bench.common import Row

ROUNDS = 3
BUSY = 2  # one per core of the machine the targets were set on
CASE = "lockstep 5 vehicles x 60 s"


@contextlib.contextmanager
def busy_loops(count: int) -> Iterator[None]:
    """``count`` CPU-bound processes, each leading a session of its own, for the block's length."""
    loops = [subprocess.Popen([sys.executable, "-c", "while True: pass"], start_new_session=True) for _ in range(count)]
    try:
        yield
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()


def run(quick: bool) -> list[Row]:
    rounds = 1 if quick else ROUNDS
    alone, beside = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(rounds):
            alone.append(timed(sys.executable, DEMO, Path(tmp), f"alone-{k}")["rtf"])
            with busy_loops(BUSY):
                beside.append(timed(sys.executable, DEMO, Path(tmp), f"beside-{k}")["rtf"])
    ratios = [b / a for a, b in zip(alone, beside)]
    ratio = statistics.median(ratios)
    details = {"alone_rtf": [round(r, 2) for r in alone], "beside_rtf": [round(r, 2) for r in beside]}
    return [
        Row("shared machine", f"{CASE}, alone", "real-time factor (median of the rounds)",
            round(statistics.median(alone), 1), "x", "-", None),
        Row("shared machine", f"{CASE}, beside {BUSY} busy loops in other sessions",
            "real-time factor (median of the rounds)", round(statistics.median(beside), 1), "x", "-", None),
        Row("shared machine", f"{CASE}, beside {BUSY} busy loops / alone", "real-time factor ratio (median of pairs)",
            round(ratio, 3), "x", ">= 0.5x", ratio >= 0.5, {**details, "rounds": rounds}),
    ]  # fmt: skip
