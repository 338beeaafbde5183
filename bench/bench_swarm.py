"""Swarm benchmarks: lockstep real-time factor, realtime loop overruns/jitter, vehicle memory, and
the system against its own floor.

Runs `swarm up` (default configuration: logins, signing, cooperation on) as real processes, reads
each run's timing.json, samples the vehicles' resident memory from /proc while they run. For each
lockstep case the floor (bench/floor.py: the same world and estimators for the same vehicles in this
one process, no bus) runs right after, so the ratio compares two runs of one sitting.
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
from bench.floor import run_floor
from bus.config import build_config

MAX_FLOOR_RATIO, MAX_OVERRUN, MAX_JITTER_US = 3.0, 0.01, 5000.0
# the control: the same realtime swarm with every loop under the fair scheduler (vehicle.process.scheduling)
FAIR_SCENARIO = 'name = "fair"\n[vehicle.realtime]\npriority = 0\n'
# the same swarm with each GNSS fix half a period off the ranging epochs (sensors.gnss_phase): reported
PHASE_SCENARIO = 'name = "phase"\n[sensors]\ngnss_phase = 0.5\n'

# The realtime case the speed issue's target is on runs three times, and its row is the median run by
# the worst vehicle's jitter p99: one run's worst p99 swings between 2 and 5 ms with the machine's
# spells (docs/benchmarks.md); every run's figures stay in the details.
REALTIME_RUNS = 3
# a target the project retired (32 vehicles in realtime on two cores): its case is reported, not held to one
RETIRED = "retired (2 cores)"
CASES = [  # (label, vehicles, mode, duration_s, target ("-": a control; RETIRED), scenario, runs)
    ("lockstep", 5, "lockstep", 60, "RTF >= 20x", None, 1),
    ("lockstep", 20, "lockstep", 20, "RTF >= 5x", None, 1),
    ("realtime 50 Hz", 5, "realtime", 20, "overruns < 1%", None, 1),
    ("realtime 50 Hz", 10, "realtime", 20, "overruns < 1%", None, 1),
    ("realtime 50 Hz", 20, "realtime", 20, "overruns < 1%", None, REALTIME_RUNS),
    ("realtime 50 Hz, fair scheduler", 20, "realtime", 20, "-", FAIR_SCENARIO, 1),
    ("realtime 50 Hz, GNSS at phase 0.5", 20, "realtime", 20, "-", PHASE_SCENARIO, REALTIME_RUNS),
    ("realtime 50 Hz", 32, "realtime", 20, RETIRED, None, 1),
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
                rss_kb = next(
                    int(line.split()[1])
                    for line in (entry / "status").read_text().splitlines()
                    if line.startswith("VmRSS")
                )
                sizes.append(rss_kb / 1024)
        except (OSError, StopIteration):
            continue
    return sizes


def run_case(vehicles: int, mode: str, duration_s: float, out: Path, scenario: Path | None = None) -> dict:
    """`swarm up` (over ``scenario`` when given) with these settings, measured."""
    name = f"{mode}-{vehicles}" + (f"-{scenario.stem}" if scenario else "")  # one directory per case
    cmd = [
        sys.executable,
        "-m",
        "cli",
        "up",
        *([str(scenario)] if scenario else []),
        "--quiet",
        "--out",
        str(out),
        "--name",
        name,
        "--vehicles",
        str(vehicles),
        "--mode",
        mode,
        "--duration",
        str(duration_s),
        "--seed",
        "1",
    ]
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
        "vehicles": vehicles,
        "mode": mode,
        "sim_s": duration_s,
        "exit_status": result.returncode,
        "real_time_factor": timing["real_time_factor"],
        "overrun_rate": sum(v["overruns"] for v in per_vehicle) / cycles if cycles else None,
        "jitter_p99_us": max((v["jitter_p99_us"] for v in per_vehicle), default=None),
        "cycle_p99_us": max((v["cycle_p99_us"] for v in per_vehicle), default=None),
        "vehicle_rss_mb_max": round(max(peak), 1) if peak else None,
        "swarm_rmse_m": summary["swarm"]["rmse_m"],
        "swarm_anees": summary["swarm"].get("anees"),
        "wall_s": timing["wall_s"],
        "dropped_stale": sum(v.get("dropped_stale", 0) for v in summary["vehicles"].values()),
        "loop_priority": min((v.get("loop_priority", 0) for v in per_vehicle), default=0),
    }


def median_run(results: list[dict]) -> dict:
    """The run whose worst vehicle's jitter p99 is the median of ``results`` (one: itself), with
    every run's jitter, overruns and stale samples under ``runs`` when there are several."""
    if len(results) == 1:
        return results[0]
    ranked = sorted(results, key=lambda r: r["jitter_p99_us"] if r["jitter_p99_us"] is not None else float("inf"))
    keep = ("jitter_p99_us", "overrun_rate", "dropped_stale", "exit_status")
    return {**ranked[len(ranked) // 2], "runs": [{k: r[k] for k in keep} for r in results]}


def floor_wall_s(vehicles: int, duration_s: float) -> float:
    """Wall time of the floor for the configuration `swarm up --vehicles N --duration D --seed 1` runs."""
    config = build_config({"world": {"vehicles": vehicles, "seed": 1}, "clock": {"duration_s": duration_s}})
    return run_floor(config).wall_s


def _scheduling(r: dict) -> str:
    """How a realtime case's loops were scheduled: SCHED_FIFO's priority, or the fair scheduler."""
    return f"SCHED_FIFO {r['loop_priority']}" if r.get("loop_priority") else "fair scheduler"


def print_table(rows: list[dict]) -> str:
    lines = [
        "| case | vehicles | sim s | RTF | floor [s] | overruns | jitter p99 [ms] | cycle p99 [ms] "
        "| loop | vehicle RSS [MB] | swarm RMSE [m] | ANEES | target |",
        "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | --- |",
    ]
    for r in rows:
        rt = r["mode"] == "realtime"
        lines.append(
            f"| {r['label']} | {r['vehicles']} | {r['sim_s']:g} | {r['real_time_factor']:.2f}x | "
            f"{r.get('floor_wall_s', float('nan')):.2f} | "
            f"{100 * r['overrun_rate']:.2f}% | {r['jitter_p99_us'] / 1000 if rt else float('nan'):.2f} | "
            f"{r['cycle_p99_us'] / 1000:.2f} | {_scheduling(r) if rt else '-'} | "
            f"{r['vehicle_rss_mb_max']} | {r['swarm_rmse_m']} | {r['swarm_anees']} | {r['target']} |"
        )
    table = "\n".join(lines).replace("nan", "-")
    print(table)
    return table


def run(quick: bool = False) -> list[Row]:
    """One headline row per case (lockstep: RTF; realtime: overrun rate) and one for vehicle memory."""
    rows, details = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for label, vehicles, mode, duration, target, scenario_text, runs in CASES[:2] if quick else CASES:
            print(f"  swarm: {label} with {vehicles} vehicles for {duration} s ({runs} run(s)) ...", flush=True)
            scenario = None
            if scenario_text is not None:
                scenario = Path(tmp) / f"case{len(details)}.toml"
                scenario.write_text(scenario_text)
            results = [run_case(vehicles, mode, duration, Path(tmp) / f"run{k}", scenario) for k in range(runs)]
            r = {"label": label, "target": target, **median_run(results)}
            details.append(r)
            case = f"{label}, {vehicles} vehicles"
            rows += lockstep_rows(case, r) if mode == "lockstep" else realtime_rows(case, r, results)
    rss = max((r["vehicle_rss_mb_max"] or 0.0) for r in details)
    rows.append(Row("swarm", "all cases", "vehicle peak RSS", rss, "MB", "<= 120 MB", rss <= 120))
    print_table(details)
    return rows


def lockstep_rows(case: str, r: dict) -> list[Row]:
    """A lockstep case's real-time factor against its target, and its wall time against the floor
    (run now, right after the case: ``r`` gains ``floor_wall_s``)."""
    need = float(r["target"].split(">=")[1].rstrip("x"))
    r["floor_wall_s"] = round(floor_wall_s(r["vehicles"], r["sim_s"]), 3)
    ratio = r["wall_s"] / r["floor_wall_s"]
    return [
        Row("swarm", case, "real-time factor", round(r["real_time_factor"], 2), "x", r["target"],
            r["real_time_factor"] >= need, r),
        Row("swarm", case, "wall time / floor", round(ratio, 2), "x",
            f"<= {MAX_FLOOR_RATIO:g}x (floor {r['floor_wall_s']:.2f} s, swarm {r['wall_s']:.2f} s)",
            ratio <= MAX_FLOOR_RATIO),
    ]  # fmt: skip


def realtime_rows(case: str, r: dict, results: list[dict]) -> list[Row]:
    """A realtime case's overruns, worst vehicle's jitter p99 (``r``: the median of ``results``) and
    samples dropped as stale (the most of any run). The control is held to no overrun or jitter
    target, a retired case to none at all: both are reported."""
    held, retired = r["target"] not in ("-", RETIRED), r["target"] == RETIRED
    runs, stale = len(results), max(x["dropped_stale"] for x in results)
    overruns, jitter = ("< 1%", "< 5 ms") if held else (r["target"], r["target"])
    return [
        Row("swarm", case, "loop overruns", round(100 * r["overrun_rate"], 2), "%", overruns,
            r["overrun_rate"] < MAX_OVERRUN if held else None, r),
        Row("swarm", case, "jitter p99" + (f" (median run of {runs})" if runs > 1 else ""),
            round(r["jitter_p99_us"] / 1000, 2), "ms", f"{jitter} ({_scheduling(r)})",
            r["jitter_p99_us"] < MAX_JITTER_US if held else None),
        Row("swarm", case, "samples dropped as stale" + (f" (most of {runs} runs)" if runs > 1 else ""), stale, "",
            RETIRED if retired else "0 (no faults)", None if retired else stale == 0),
    ]  # fmt: skip
