"""Monte Carlo of a scenario of ``ar-ekf-slam-3d`` vehicles (default scenarios/uav-3d.toml) flown in one
process (experiments.uav3d_flights): per seed and vehicle the horizontal RMSE, the 2-dof ANEES of the
published position and the resets, then the pooled ANEES against its two-sided 95% band. The table of
docs/ar-slam.md ("Through the processes").

    python tools/uav3d.py [--scenario scenarios/uav-3d.toml] [--seeds 8] [--jobs 2] [--set world.radius_m=60]
        [--json docs/data/uav3d-monte-carlo.json]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
from pathlib import Path

import numpy as np
from scipy import stats

from bus.config import build_config
from experiments.uav3d_flights import FlightScore, fly_in_process
from launch.scenario import load_scenario, overlay


def flight(arguments: tuple[Path, int, dict]) -> dict[int, FlightScore]:
    scenario, seed, overrides = arguments
    data = overlay(load_scenario(scenario), overrides)
    data["world"] = {**data.get("world", {}), "seed": seed}
    return fly_in_process(build_config(data))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", type=Path, default=Path("scenarios/uav-3d.toml"))
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--set", action="append", default=[], help="section.key=value, e.g. world.radius_m=60")
    parser.add_argument("--json", type=Path, help="also write the rows and the summary here")
    args = parser.parse_args()
    overrides = _overrides(args.set)
    seeds = range(1, args.seeds + 1)
    with multiprocessing.get_context("spawn").Pool(args.jobs) as pool:
        runs = pool.map(flight, [(args.scenario, seed, overrides) for seed in seeds])
    rows = [
        {"seed": seed, "vehicle": vid, "rmse_m": s.rmse_m, "max_error_m": float(s.error_m.max()), "anees": s.anees}
        | {"resets": s.resets, "height_rmse_m": s.height_rmse_m, "height_anees": float(np.mean(s.height_nees))}
        for seed, run in zip(seeds, runs)
        for vid, s in run.items()
    ]
    print("| seed | vehicle | RMSE m | max error m | ANEES (2 dof) | resets | height RMSE m | height ANEES (1 dof) |")
    print("|---|---|---|---|---|---|---|---|")
    for r in rows:
        scores = (f"{r[k]:.2f}" for k in ("rmse_m", "max_error_m", "anees"))
        heights = (f"{r[k]:.2f}" for k in ("height_rmse_m", "height_anees"))
        cells = (r["seed"], r["vehicle"], *scores, r["resets"], *heights)
        print("| " + " | ".join(map(str, cells)) + " |")
    summary = {"scenario": str(args.scenario), "overrides": overrides} | _consistency(
        [s for run in runs for s in run.values()]
    )
    print()
    print(
        f"{summary['flights']} flights: median per-flight ANEES {summary['median_flight_anees']:.2f}, "
        f"pooled {summary['pooled_anees']:.2f}"
    )
    (low, high), inside, below = summary["band"], summary["instants_in_band"], summary["instants_below_band"]
    print(f"instants whose ANEES across flights is in [{low:.2f}, {high:.2f}]: {inside:.0%} ({below:.0%} below)")
    print(f"swarm RMSE {summary['swarm_rmse_m']:.2f} m")
    height = summary["height"]
    (low, high), inside, below = height["band"], height["instants_in_band"], height["instants_below_band"]
    print(
        f"height: RMSE {height['rmse_m']:.2f} m, median per-flight ANEES {height['median_flight_anees']:.2f}, "
        f"instants in [{low:.2f}, {high:.2f}]: {inside:.0%} ({below:.0%} below)"
    )
    if args.json:
        args.json.write_text(json.dumps({"summary": summary, "flights": rows}, indent=1) + "\n")


def _overrides(items: list[str]) -> dict:
    """``--set section.key=value`` items as a scenario overlay (values in JSON: a number, or a list)."""
    out: dict = {}
    for item in items:
        key, _, value = item.partition("=")
        section, _, name = key.partition(".")
        out.setdefault(section, {})[name] = json.loads(value)
    return out


def _consistency(flights: list[FlightScore]) -> dict:
    """The flights' pooled statistics: the median per-flight and the pooled ANEES, the share of
    instants whose ANEES across the flights is inside (and below) its two-sided 95% band, that band,
    and the RMSE of them all."""
    count = len(flights)
    per_flight = np.array([f.anees for f in flights])
    samples = min(len(f.nees) for f in flights)
    low, high = stats.chi2.ppf([0.025, 0.975], 2 * count) / count  # ANEES across flights at one instant
    at = np.array([f.nees[:samples] for f in flights]).mean(axis=0)  # each instant's ANEES across them
    return {
        "flights": count,
        "median_flight_anees": float(np.median(per_flight)),
        "pooled_anees": float(np.concatenate([f.nees for f in flights]).mean()),
        "instants_in_band": float(np.mean((at >= low) & (at <= high))),
        "instants_below_band": float(np.mean(at < low)),
        "band": [float(low), float(high)],
        "swarm_rmse_m": float(np.sqrt(np.mean(np.concatenate([f.error_m**2 for f in flights])))),
        "height": _height(flights),
    }


def _height(flights: list[FlightScore]) -> dict:
    """The heights' pooled statistics (1 dof): the median per-flight and the pooled ANEES, the share of
    instants whose ANEES across the flights is inside (and below) its band, and the RMSE of them all."""
    count, samples = len(flights), min(len(f.height_nees) for f in flights)
    low, high = stats.chi2.ppf([0.025, 0.975], count) / count
    at = np.array([f.height_nees[:samples] for f in flights]).mean(axis=0)
    return {
        "median_flight_anees": float(np.median([np.mean(f.height_nees) for f in flights])),
        "pooled_anees": float(np.concatenate([f.height_nees for f in flights]).mean()),
        "instants_in_band": float(np.mean((at >= low) & (at <= high))),
        "instants_below_band": float(np.mean(at < low)),
        "band": [float(low), float(high)],
        "rmse_m": float(np.sqrt(np.mean(np.concatenate([f.height_error_m**2 for f in flights])))),
    }


if __name__ == "__main__":
    main()
