"""Campaign benchmarks: a cooperative experiment (``SEEDS`` seeds of the default variants,
shortened to ``JAM_S`` of jam) flown one run at a time (``--workers 1``) and as a campaign on this
machine's local cluster (workers from the cores), in one sitting; runs per hour and CPU seconds per
run; and the projection to 16 and 64 cores from the CPU one run takes, with what stops it holding:
the memory one run keeps (its processes' resident memory, summed) against the machine's, and the
router sessions (one router per run: sessions per run = its processes)."""

from __future__ import annotations

import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import Row

SEEDS, JAM_S = 2, 30.0
MACHINE_MEMORY_GB = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 2**30


def run_memory_mb(marker: str) -> float:
    """Resident memory (MB) of every process whose command line holds ``marker``, summed."""
    total = 0
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            if marker not in (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace"):
                continue
            status = (entry / "status").read_text().splitlines()
            total += next(int(line.split()[1]) for line in status if line.startswith("VmRSS"))
        except (OSError, StopIteration):
            continue
    return total / 1024


def fly(workers: int | None, out: Path) -> tuple[float, float, int, float]:
    """(wall s, CPU s of every process, runs, the most memory (MB) the runs' processes held at once)
    of the cooperative experiment as a campaign."""
    command = [sys.executable, "-m", "cli", "experiment", "cooperative", "--seeds", str(SEEDS), "--jam", str(JAM_S),
               "--out", str(out), "--quiet"] + (["--workers", str(workers)] if workers else [])  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    peak = 0.0
    while process.poll() is None:
        peak = max(peak, run_memory_mb(str(out / "cooperative") + "/"))
        time.sleep(0.5)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    runs = len(list((out / "cooperative").glob("*/row.json")))
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), runs, peak


def run(quick: bool) -> list[Row]:
    cores = len(os.sched_getaffinity(0))
    with tempfile.TemporaryDirectory() as tmp:
        one_wall, one_cpu, runs, run_mb = fly(1, Path(tmp) / "one")
        many_wall, many_cpu, _, _ = fly(None, Path(tmp) / "many")
    cpu_per_run = one_cpu / runs
    per_hour = 3600.0 * runs / many_wall
    rows = [
        Row(
            "campaign",
            f"cooperative, {SEEDS} seeds x 7 runs ({JAM_S:g} s jam), {cores} cores",
            "wall: one at a time / campaign",
            round(one_wall / many_wall, 2),
            "x",
            "-",
            None,
            {"one_at_a_time_s": round(one_wall, 1), "campaign_s": round(many_wall, 1), "runs": runs},
        ),
        Row("campaign", "local cluster", "runs per hour", round(per_hour), "runs/h", "-", None),
        Row(
            "campaign",
            "local cluster",
            "CPU per run",
            round(cpu_per_run, 2),
            "s",
            "-",
            None,
            {"campaign_cpu_s": round(many_cpu, 1)},
        ),  # fmt: skip
    ]
    for target in (16, 64):
        projected = 3600.0 * target / cpu_per_run
        rows.append(
            Row(
                "campaign",
                f"projection to {target} cores",
                "runs per hour (CPU-bound)",
                round(projected),
                "runs/h",
                "-",
                None,
                {
                    "memory_per_run_mb": round(run_mb),
                    "runs_at_once_needed": int(target // 2),
                    "runs_the_memory_holds": int(MACHINE_MEMORY_GB * 1024 // max(run_mb, 1.0)),
                    "holds_while": "the runs at once fit the machine's memory; one router per run",
                },
            )
        )
    return rows
