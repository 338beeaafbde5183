"""Swarm benchmarks: lockstep real-time factor, realtime loop overruns/jitter, vehicle memory.

Runs `swarm up` as real processes, reads each run's timing.json, samples the vehicles' resident
memory from /proc while they run, prints a table and writes bench/results.json.
Run by `make bench` through bench/run_all.py.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

from bench.common import Row

CASES = [  # (label, vehicles, mode, duration_s, target)
    ("lockstep", 5, "lockstep", 60, "RTF >= 20x"),
    ("lockstep", 20, "lockstep", 20, "-"),
    ("realtime 50 Hz", 5, "realtime", 20, "overruns < 1%"),
    ("realtime 50 Hz", 10, "realtime", 20, "overruns < 1%"),
    ("realtime 50 Hz", 20, "realtime", 20, "overruns < 1%"),
    ("realtime 50 Hz", 32, "realtime", 20, "overruns < 1%"),
]


def vehicle_rss_mb(marker: str) -> list[float]:
    """Resident memory (MB) of every running vehicle process whose command line holds ``marker``."""
    sizes = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            if marker in cmd and " vehicle " in cmd:
                rss_kb = next(int(l.split()[1]) for l in (entry / "status").read_text().splitlines() if l.startswith("VmRSS"))
                sizes.append(rss_kb / 1024)
        except (OSError, StopIteration):
            continue
    return sizes


def run_case(vehicles: int, mode: str, duration_s: float, out: Path) -> dict:
    name = f"{mode}-{vehicles}"
    cmd = [sys.executable, "-m", "groundstation.cli", "up", "--quiet", "--out", str(out), "--name", name,
           "--vehicles", str(vehicles), "--mode", mode, "--duration", str(duration_s), "--seed", "1"]
    peak: list[float] = []
    done = threading.Event()

    def sample() -> None:
        while not done.wait(0.5):
            peak.extend(vehicle_rss_mb(str(out / name)))

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    done.set()
    sampler.join()
    timing = json.loads((out / name / "timing.json").read_text())
    summary = json.loads((out / name / "summary.json").read_text())
    per_vehicle = timing["vehicles"].values()
    cycles = sum(v["cycles"] for v in per_vehicle)
    return {
        "vehicles": vehicles, "mode": mode, "sim_s": duration_s, "exit_status": result.returncode,
        "real_time_factor": timing["real_time_factor"],
        "overrun_rate": sum(v["overruns"] for v in per_vehicle) / cycles if cycles else None,
        "jitter_p99_us": max((v["jitter_p99_us"] for v in per_vehicle), default=None),
        "cycle_p99_us": max((v["cycle_p99_us"] for v in per_vehicle), default=None),
        "vehicle_rss_mb_max": round(max(peak), 1) if peak else None,
        "swarm_rmse_m": summary["swarm"]["rmse_m"],
    }


def print_table(rows: list[dict]) -> str:
    lines = ["| case | vehicles | sim s | RTF | overruns | jitter p99 [ms] | cycle p99 [ms] | vehicle RSS [MB] | swarm RMSE [m] | target |",
             "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    for r in rows:
        rt = r["mode"] == "realtime"
        lines.append(f"| {r['label']} | {r['vehicles']} | {r['sim_s']:g} | {r['real_time_factor']:.2f}x | "
                     f"{100 * r['overrun_rate']:.2f}% | {r['jitter_p99_us'] / 1000 if rt else float('nan'):.2f} | "
                     f"{r['cycle_p99_us'] / 1000:.2f} | {r['vehicle_rss_mb_max']} | {r['swarm_rmse_m']} | {r['target']} |")
    table = "\n".join(lines).replace("nan", "-")
    print(table)
    return table


def run(quick: bool = False) -> list[Row]:
    """One headline row per case (lockstep: RTF; realtime: overrun rate) and one for vehicle memory."""
    rows, details = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for label, vehicles, mode, duration, target in CASES[:2] if quick else CASES:
            print(f"  swarm: {label} with {vehicles} vehicles for {duration} s ...", flush=True)
            r = {"label": label, "target": target, **run_case(vehicles, mode, duration, Path(tmp))}
            details.append(r)
            if mode == "lockstep":
                met = None if target == "-" else r["real_time_factor"] >= 20
                rows.append(Row("swarm", f"{label}, {vehicles} vehicles", "real-time factor",
                                round(r["real_time_factor"], 2), "x", target, met, r))
            else:
                rows.append(Row("swarm", f"{label}, {vehicles} vehicles", "loop overruns",
                                round(100 * r["overrun_rate"], 2), "%", "< 1%", r["overrun_rate"] < 0.01, r))
    rss = max((r["vehicle_rss_mb_max"] or 0.0) for r in details)
    rows.append(Row("swarm", "all cases", "vehicle peak RSS", rss, "MB", "<= 120 MB", rss <= 120))
    print_table(details)
    return rows
