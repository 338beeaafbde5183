"""`swarm experiment lateness`: what late inputs cost a swarm, in accuracy and in honesty. Three
vehicles (one on each kind of trajectory) fly with their IMU and wheel odometry held back by a link
delay fault for most of the run; each delay is flown with the filters' walk of overdue inputs
(``sensors.speed_walk_mps_rtsec``, ``sensors.yaw_rate_walk_radps_rtsec``: vehicle.estimators.inputs)
and without it, on every seed, through real processes in lockstep (the lateness is the fault's, so
the runs are reproducible). Per delay and case: position RMSE, ANEES, and how many vehicles stayed
inside their NEES band (docs/decisions/realtime-restart.md).

The recipe's example (docs/tutorial/adding-an-experiment.md): an experiment is this module (``plan``
its runs, ``measure`` what each run says, ``conclude`` the table and the figure) and its entry in
experiments.registry, whose parameters become the command's options and the campaign's grid.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bus.config import build_config
from bus.errors import ConfigError
from experiments.conclusions import completed, write_experiment
from launch.runspec import RunSpec

LATE_FROM_S = 5.0  # the feed is on time for the first seconds (the filters start), late after
NO_WALK = {"speed_walk_mps_rtsec": 0.0, "yaw_rate_walk_radps_rtsec": 0.0}
CASES = ("walk", "no-walk")


@dataclass(frozen=True)
class Case:
    delay_s: float
    case: str  # walk: the datasheet's walk of overdue inputs; no-walk: held inputs taken as measured
    seed: int

    @property
    def name(self) -> str:
        return f"delay-{self.delay_s:g}s-{self.case}-seed{self.seed}"


def lateness_config(case: Case, duration_s: float) -> dict[str, Any]:
    """The configuration of one run (validated: a one-line ConfigError names what is wrong)."""
    late = [
        {"name": f"late-{topic}", "kind": "delay", "topic": topic, "delay_s": case.delay_s, "start_s": LATE_FROM_S}
        for topic in ("imu", "odom")
        if case.delay_s > 0
    ]
    config = {
        "name": case.name,
        "world": {"vehicles": 3, "seed": case.seed, "trajectories": ["circle", "figure8", "waypoints"]},
        "clock": {"duration_s": duration_s},
        "sensors": NO_WALK if case.case == "no-walk" else {},
        "faults": late,
    }
    return build_config(config).model_dump(mode="json")


def plan(seeds: int, first_seed: int, delays: str, duration: float) -> list[RunSpec]:
    """Every delay in both cases on every seed."""
    if duration <= LATE_FROM_S:
        raise ConfigError(f"--duration must be longer than the {LATE_FROM_S:g} s the feed is on time")
    return [
        RunSpec(c.name, f"{c.delay_s:g}s-{c.case}", c.seed, lateness_config(c, duration), measure=f"{__name__}:measure")
        for c in _cases(seeds, first_seed, delays)
    ]


def measure(run_dir: Path) -> dict[str, Any]:
    """What a run says: each vehicle's RMSE and ANEES, and whether its NEES stayed inside its band."""
    vehicles = json.loads((run_dir / "summary.json").read_text())["vehicles"]
    return {
        "rmse_m": [v["rmse_m"] for v in vehicles.values()],
        "anees": [v["anees"] for v in vehicles.values()],
        "inside": [bool(v["consistency"]["inside"]) for v in vehicles.values()],
    }


def conclude(rows: list[dict], folder: Path, *, seeds: int, first_seed: int, delays: str, duration: float) -> list[str]:
    """experiment.json and the figure from the runs that completed; a line per delay and case."""
    done = completed(rows, _cases(seeds, first_seed, delays), folder)
    table: dict[str, dict[str, Any]] = {}
    for case, run_dir in sorted(done.items(), key=lambda item: (item[0].delay_s, item[0].case, item[0].seed)):
        row = table.setdefault(f"{case.delay_s:g} s, {case.case}", {"delay_s": case.delay_s, "case": case.case})
        for key, values in measure(run_dir).items():
            row.setdefault(key, []).extend(values)
    for row in table.values():
        row["rmse_m"] = round(float(np.sqrt(np.mean(np.square(row["rmse_m"])))), 3)
        row["anees_mean"], row["anees_max"] = round(float(np.mean(row["anees"])), 2), round(max(row["anees"]), 2)
        row["inside"] = f"{sum(row['inside'])} of {len(row['inside'])}"
    write_experiment(folder, {"late_from_s": LATE_FROM_S, "duration_s": duration, "cases": table})
    if table:
        _figure(table).savefig(folder / "anees_by_delay.png", dpi=100)
    return [
        f"  {name:<20} RMSE {row['rmse_m']} m  ANEES {row['anees_mean']} (max {row['anees_max']})  "
        f"inside their band {row['inside']}"
        for name, row in table.items()
    ]


def _cases(seeds: int, first_seed: int, delays: str) -> list[Case]:
    try:
        chosen = sorted({float(d) for d in delays.split(",") if d.strip()})
    except ValueError:
        raise ConfigError(f"--delays must be seconds separated by commas, got {delays!r}") from None
    if not chosen or any(not 0 <= d <= 2 for d in chosen):
        raise ConfigError(f"--delays must be between 0 and 2 s, got {delays!r}")
    return [Case(d, c, s) for s in range(first_seed, first_seed + seeds) for d in chosen for c in CASES]


def _figure(table: dict[str, dict[str, Any]]):
    """ANEES (each vehicle of each seed a dot, the mean a line) against the delay, per case."""
    from matplotlib.figure import Figure

    from bus import statistics

    fig = Figure(figsize=(7.0, 4.0), layout="constrained")
    ax = fig.subplots()
    for k, case in enumerate(CASES):
        rows = [row for row in table.values() if row["case"] == case]
        delays = [row["delay_s"] for row in rows]
        for row in rows:
            ax.plot([row["delay_s"]] * len(row["anees"]), row["anees"], ".", color=f"C{k}", alpha=0.5)
        ax.plot(delays, [row["anees_mean"] for row in rows], "-", color=f"C{k}", label=case)
    ax.axhline(statistics.POSE_NEES_DOF, color="black", lw=0.8, ls=":", label="3 (consistent)")
    ax.set_yscale("log")
    ax.set_xlabel("IMU and odometry delay [s]")
    ax.set_ylabel("vehicle ANEES (3 dof)")
    ax.set_title("late inputs: with the walk of overdue inputs and without it", fontsize="medium")
    ax.legend(fontsize="small")
    return fig
