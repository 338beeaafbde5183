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
    overrides: dict = {}
    for item in args.set:
        key, _, value = item.partition("=")
        section, _, name = key.partition(".")
        overrides.setdefault(section, {})[name] = json.loads(value)  # a number, or a list in JSON
    seeds = range(1, args.seeds + 1)
    with multiprocessing.get_context("spawn").Pool(args.jobs) as pool:
        runs = pool.map(flight, [(args.scenario, seed, overrides) for seed in seeds])
    print("| seed | vehicle | RMSE m | max error m | ANEES (2 dof) | resets |")
    print("|---|---|---|---|---|---|")
    pooled = []
    for seed, run in zip(seeds, runs):
        for vid, score in run.items():
            pooled.append(score.nees)
            cells = (seed, vid, f"{score.rmse_m:.2f}", f"{score.error_m.max():.2f}", f"{score.anees:.2f}", score.resets)
            print("| " + " | ".join(map(str, cells)) + " |")
    flights = len(pooled)
    nees = np.concatenate(pooled)
    per_flight = np.array([p.mean() for p in pooled])
    samples = min(len(p) for p in pooled)
    low, high = stats.chi2.ppf([0.025, 0.975], 2 * flights) / flights  # ANEES across flights at one instant
    print()
    print(f"{flights} flights: median per-flight ANEES {np.median(per_flight):.2f}, pooled {nees.mean():.2f}")
    at = np.array([p[:samples] for p in pooled]).mean(axis=0)  # each instant's ANEES across the flights
    inside, below = np.mean((at >= low) & (at <= high)), np.mean(at < low)
    print(f"instants whose ANEES across flights is in [{low:.2f}, {high:.2f}]: {inside:.0%} ({below:.0%} below)")
    rmse = np.sqrt(np.mean(np.concatenate([run[v].error_m ** 2 for run in runs for v in run])))
    print(f"swarm RMSE {rmse:.2f} m")
    if args.json:
        rows = [
            {"seed": seed, "vehicle": vid, "rmse_m": s.rmse_m, "max_error_m": float(s.error_m.max()), "anees": s.anees}
            | {"resets": s.resets}
            for seed, run in zip(seeds, runs)
            for vid, s in run.items()
        ]
        summary = {
            "scenario": str(args.scenario),
            "overrides": overrides,
            "flights": flights,
            "median_flight_anees": float(np.median(per_flight)),
            "pooled_anees": float(nees.mean()),
            "instants_in_band": float(inside),
            "instants_below_band": float(below),
            "band": [float(low), float(high)],
            "swarm_rmse_m": float(rmse),
        }
        args.json.write_text(json.dumps({"summary": summary, "flights": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
