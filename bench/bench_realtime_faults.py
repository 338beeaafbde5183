"""Realtime runs under the supervisor's restart policy and under a chaos timeline, each beside its
control measured in the same sitting.

- `--restart on-failure` against the plain run: the same realtime swarm (8 vehicles x 60 s, seed 4),
  in interleaved pairs; per pair the ratio of the swarm's overruns, worst jitter p99 and late-fused
  input samples, the row the median pair's. Targets: each within 1.2x of the plain run; every
  vehicle's ANEES inside its band in both.
- a chaos timeline (`--chaos 3`, `--chaos 7`, 5 vehicles x 60 s, `--restart on-failure`) in realtime
  against the same timeline in lockstep. Targets: the realtime swarm ANEES within its 95 % band and
  within 1.5x of lockstep's; overruns below 1 %.

Run by `make bench` through bench/run_all.py (`--only realtime_faults`).
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from bench.common import Row

PAIRS = 3
RESTART_CASE = ("--vehicles", "8", "--duration", "60", "--mode", "realtime", "--seed", "4")
CHAOS_SEEDS = (3, 7)
MAX_RATIO, MAX_CHAOS_RATIO, MAX_OVERRUN = 1.2, 1.5, 0.01


def swarm_up(out: Path, name: str, *args: str) -> dict:
    """One `swarm up` run, measured: its summary's and timing's per-vehicle figures."""
    cmd = [sys.executable, "-m", "cli", "up", "--quiet", "--no-report", "--out", str(out), "--name", name, *args]
    result = subprocess.run(cmd, capture_output=True, text=True, timeout=1800)
    if result.returncode != 0:
        raise RuntimeError(f"swarm up {' '.join(args)} failed: {result.stderr[-500:]}")
    summary = json.loads((out / name / "summary.json").read_text())
    timing = json.loads((out / name / "timing.json").read_text())["vehicles"]
    vehicles = summary["vehicles"]
    cycles = sum(t["cycles"] for t in timing.values())
    return {
        "overrun_rate": sum(t["overruns"] for t in timing.values()) / cycles,
        "jitter_p99_us": max(t["jitter_p99_us"] or 0.0 for t in timing.values()),
        # ranging fixes come after their cycle by design: the late inputs are the rest
        "late_inputs": sum(v["late_fused"] - v["v2v_fused"] for v in vehicles.values()),
        "anees": {vid: v["anees"] for vid, v in vehicles.items()},
        "outside_band": sorted(vid for vid, v in vehicles.items() if not v["consistency"]["inside"]),
        "swarm_anees": summary["swarm"]["anees"],
        "swarm_band": summary["swarm"]["nees_bounds_95"],
        "swarm_rmse_m": summary["swarm"]["rmse_m"],
    }


def _ratio(a: float, b: float) -> float:
    """a / b with a floor of 1 under both (overruns per 10,000 cycles, jitter in ms, samples): below it
    two runs of the same swarm differ by more than the ratio asked, so two such figures compare as equal."""
    return max(a, 1.0) / max(b, 1.0)


def restart_rows(out: Path) -> list[Row]:
    pairs = []
    for k in range(PAIRS):
        plain = swarm_up(out, f"plain-{k}", *RESTART_CASE)
        restart = swarm_up(out, f"restart-{k}", *RESTART_CASE, "--restart", "on-failure")
        pairs.append((plain, restart))
    rows = []
    for metric, key, scale in (
        ("loop overruns", "overrun_rate", 1e4),  # per 10,000 cycles, so that a ratio of counts means something
        ("worst jitter p99", "jitter_p99_us", 1e-3),
        ("late-fused input samples", "late_inputs", 1.0),
    ):
        ratios = [_ratio(r[key] * scale, p[key] * scale) for p, r in pairs]
        median = statistics.median(ratios)
        details = {"ratios": ratios, "plain": [p[key] for p, _ in pairs], "restart": [r[key] for _, r in pairs]}
        rows.append(Row("realtime_faults", "8 vehicles x 60 s, --restart on-failure / plain", f"{metric} ratio",
                        round(median, 3), "x", f"<= {MAX_RATIO:g}x (median of {PAIRS} pairs)",
                        median <= MAX_RATIO, details))  # fmt: skip
    outside = sum(len(p["outside_band"]) + len(r["outside_band"]) for p, r in pairs)
    anees = {"plain": [p["anees"] for p, _ in pairs], "restart": [r["anees"] for _, r in pairs]}
    rows.append(Row("realtime_faults", "8 vehicles x 60 s, both policies", "vehicles outside their NEES band",
                    outside, "", f"0 of {2 * PAIRS * 8}", outside == 0, anees))  # fmt: skip
    return rows


def chaos_rows(out: Path) -> list[Row]:
    rows = []
    for seed in CHAOS_SEEDS:
        args = ("--chaos", str(seed), "--restart", "on-failure")
        realtime = swarm_up(out, f"chaos{seed}-realtime", *args, "--mode", "realtime")
        lockstep = swarm_up(out, f"chaos{seed}-lockstep", *args, "--mode", "lockstep")
        ratio = realtime["swarm_anees"] / lockstep["swarm_anees"]
        low, high = realtime["swarm_band"]
        case = f"--chaos {seed}, 5 vehicles x 60 s, realtime / lockstep"
        details = {"realtime": realtime, "lockstep": lockstep}
        rows += [
            Row("realtime_faults", case, "swarm ANEES ratio", round(ratio, 3), "x",
                f"<= {MAX_CHAOS_RATIO:g}x, realtime {realtime['swarm_anees']:.2f} inside [{low:.2f}, {high:.2f}]",
                ratio <= MAX_CHAOS_RATIO and low <= realtime["swarm_anees"] <= high, details),
            Row("realtime_faults", case, "realtime loop overruns", round(100 * realtime["overrun_rate"], 3), "%",
                "< 1%", realtime["overrun_rate"] < MAX_OVERRUN),
        ]  # fmt: skip
    return rows


def run(quick: bool = False) -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        print("  realtime_faults: --restart on-failure against plain, interleaved pairs ...", flush=True)
        rows = [] if quick else restart_rows(out)
        print("  realtime_faults: chaos timelines, realtime against lockstep ...", flush=True)
        return rows + chaos_rows(out)
