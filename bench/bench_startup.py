"""Start-up benchmarks: what each process role loads and costs before its loop
(bench/startup.py), and the CPU a whole 10-vehicle swarm spends to start and stop, against the code
the issue was filed on (``BEFORE``, built from the repository's history by bench/baseline.py), the
two interleaved in one sitting (medians of ``ROUNDS``); and a one-minute MRCLAM replay with its
calibration kept from an earlier replay against calibrating (launch.calibration_cache)."""

from __future__ import annotations

import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.baseline import baseline_python, checkout_of, swarm_of
from bench.common import Row
from bench.startup import ROLES, probe

BEFORE = "4abe413"  # main before the start-up work (the yardstick of its targets)
ROUNDS = 3
VEHICLE_RSS_MB = 65.0
EXCERPT = Path(__file__).resolve().parents[1] / "tests" / "data" / "MRCLAM_Dataset6_first240s.tar.xz"


def swarm_cpu_s(python: Path | str, vehicles: int, duration_s: float, out: Path, name: str) -> float:
    """CPU seconds (user + system, every process) of one lockstep `swarm up` run with ``python``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(
        [swarm_of(python), "up", "--vehicles", str(vehicles), "--duration", str(duration_s), "--mode",
         "lockstep", "--seed", "5", "--quiet", "--no-report", "--out", str(out), "--name", name],
        check=True, capture_output=True, cwd=checkout_of(python),
    )  # fmt: skip
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def run(quick: bool) -> list[Row]:
    rows = []
    for name in ROLES:
        found = min((probe(name) for _ in range(1 if quick else 3)), key=lambda s: s.cpu_s)
        is_vehicle = name == "vehicle"
        rows.append(
            Row(
                "startup",
                f"process start: {name}",
                "resident memory after start-up",
                round(found.rss_mb, 1),
                "MB",
                f"<= {VEHICLE_RSS_MB:g} MB" if is_vehicle else "-",
                found.rss_mb <= VEHICLE_RSS_MB if is_vehicle else None,
                {"cpu_s": round(found.cpu_s, 3), "loads": list(found.modules)},
            )
        )
    before = baseline_python(BEFORE)
    cpu: dict[str, list[float]] = {"now": [], "before": []}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(1 if quick else ROUNDS):
            cpu["now"].append(swarm_cpu_s(sys.executable, 10, 1.0, Path(tmp), f"now-{k}"))
            cpu["before"].append(swarm_cpu_s(before, 10, 1.0, Path(tmp), f"before-{k}"))
    now, then = statistics.median(cpu["now"]), statistics.median(cpu["before"])
    rows.append(
        Row(
            "startup",
            "10-vehicle swarm, lockstep, 1 s: start, 1 s, stop",
            f"CPU against {BEFORE}",
            round(now / then, 3),
            "x",
            "<= 0.5x",
            now / then <= 0.5,
            {"cpu_s": round(now, 2), "cpu_s_before": round(then, 2), "rounds": len(cpu["now"])},
        )
    )
    rows.append(replay_row(1 if quick else ROUNDS))
    return rows


def replay_wall_s(out: Path, name: str, cache: str) -> float:
    """Wall seconds of `swarm replay mrclam` on the first minute after the default calibration
    interval of the data set 6 excerpt, with ``SWARMLOC_CACHE`` = ``cache``."""
    start = time.perf_counter()
    subprocess.run(
        [sys.executable, "-m", "cli", "replay", "mrclam", str(EXCERPT), "--duration", "60", "--quiet",
         "--no-report", "--out", str(out), "--name", name],
        check=True, capture_output=True, env={**os.environ, "SWARMLOC_CACHE": cache},
    )  # fmt: skip
    return time.perf_counter() - start


def replay_row(rounds: int) -> Row:
    """Each round: a replay that calibrates (the cache off), then one that reads the calibration a
    first replay kept in a fresh folder (that first one not timed)."""
    walls: dict[str, list[float]] = {"calibrating": [], "kept": []}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(rounds):
            walls["calibrating"].append(replay_wall_s(Path(tmp), f"cold-{k}", "off"))
            cache = str(Path(tmp) / f"cache-{k}")
            replay_wall_s(Path(tmp), f"first-{k}", cache)
            walls["kept"].append(replay_wall_s(Path(tmp), f"kept-{k}", cache))
    kept, calibrating = statistics.median(walls["kept"]), statistics.median(walls["calibrating"])
    return Row(
        "startup",
        "MRCLAM replay, 5 robots, 60 s: calibration kept from an earlier replay",
        "wall against calibrating",
        round(kept / calibrating, 3),
        "x",
        "-",
        None,
        {"wall_s": round(kept, 2), "wall_s_calibrating": round(calibrating, 2), "rounds": rounds},
    )
