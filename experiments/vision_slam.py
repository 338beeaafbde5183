"""`swarm experiment vision-slam`: the vision EKF-SLAM paper's experiment (figures 4 and 5) on the
simulator: one UAV on a circle and one on a figure-8 over the terrain, GNSS jammed for the whole
flight, flown twice on the same seed: with ``ekf-slam`` on camera frames, and with dead reckoning
(``ekf`` on odometry and gyro alone). Each flight is an ordinary run directory with its report (the
map draws the landmarks with 3-sigma ellipses); the experiment adds the comparison figures and
``experiment.json``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from bus import statistics
from bus.config import SwarmConfig, build_config
from groundstation.report.rundata import RunData, load_run
from launch.runspec import RunSpec

FLIGHTS = (("slam", "ekf-slam", "EKF-SLAM (camera)"), ("dead-reckoning", "ekf", "dead reckoning"))


SURVEYED_START = {"prior_sigma_m": 0.1, "prior_heading_sigma_rad": 0.005}


def vision_slam_config(estimator: str, *, name: str, seed: int, duration_s: float) -> SwarmConfig:
    """Two camera UAVs (circle, figure-8), no GNSS anywhere, no cooperation: the paper's setting. As
    in the paper, the map is anchored at a well-known start pose (``SURVEYED_START``, both flights):
    without GNSS nothing observes the launch heading, and the default launch survey's 0.05 rad would
    rotate the whole map (about 2 m at 40 m from the pad), hiding what SLAM does."""
    return build_config(
        {
            "name": name,
            "world": {"vehicles": 2, "seed": seed, "trajectories": ["circle", "figure8"]},
            "clock": {"duration_s": duration_s},
            "sensors": {"camera_rate_hz": 10, **SURVEYED_START},
            "vehicle": {"estimator": estimator, "cooperation": {"enabled": False}},
            "faults": [{"name": "no-gnss", "kind": "jam-gnss", "center_m": [0.0, 0.0], "radius_m": 500.0}],
        }
    )


def plan(seed: int, duration: float) -> list[RunSpec]:
    """The two flights on ``seed``."""
    return [
        RunSpec(
            name,
            name,
            seed,
            vision_slam_config(estimator, name=name, seed=seed, duration_s=duration).model_dump(mode="json"),
            report=True,
        )
        for name, estimator, _ in FLIGHTS
    ]


def conclude(rows: list[dict], folder: Path, **params: Any) -> list[str]:
    """experiment.json and the figures (each flight has its report: its map with the landmarks)."""
    done = {row["run"] for row in rows if row.get("status") == "complete"}
    runs = {name: folder / name for name, _, _ in FLIGHTS if name in done}
    lines = [f"report: {run / 'report.html'}" for run in runs.values()]
    table, figures = compare(folder, runs)
    for name, flight in table.items():
        landmarks = {vid: v.get("landmarks") for vid, v in flight["vehicles"].items()}
        lines.append(
            f"{name}: {flight['status']}, swarm RMSE {flight['swarm_rmse_m']} m, ANEES {flight['swarm_anees']}"
            + (f", landmarks {landmarks}" if any(landmarks.values()) else "")
        )
    return lines + [f"figure: {f}" for f in figures]


def compare(folder: Path, runs: dict[str, Path]) -> tuple[dict[str, Any], list[Path]]:
    """experiment.json (RMSE, ANEES, map size per flight and vehicle) and the comparison figures."""
    data = {name: load_run(path) for name, path in runs.items()}
    table = {name: _flight_summary(d) for name, d in data.items()}
    (folder / "experiment.json").write_text(json.dumps(table, indent=2, sort_keys=True) + "\n")
    written = []
    for stem, build in (("error_vs_dead_reckoning", error_comparison), ("nees_vs_dead_reckoning", nees_comparison)):
        figure = build(data)
        if figure is not None:
            path = folder / f"{stem}.png"
            figure.savefig(path, dpi=100)
            written.append(path)
    return table, written


def _flight_summary(data: RunData) -> dict[str, Any]:
    s = data.summary or {}
    vehicles = {
        vid: {key: v.get(key) for key in ("rmse_m", "anees", "landmarks", "samples")}
        for vid, v in s.get("vehicles", {}).items()
    }
    return {
        "status": s.get("status"),
        "swarm_rmse_m": s.get("swarm", {}).get("rmse_m"),
        "swarm_anees": s.get("swarm", {}).get("anees"),
        "vehicles": vehicles,
    }


def error_comparison(data: dict[str, RunData]) -> Figure | None:
    """Position error of each vehicle over time with its 3-sigma envelope, SLAM against dead reckoning."""
    vehicles = sorted({v for d in data.values() for v in d.vehicles})
    if not vehicles:
        return None
    fig = Figure(figsize=(9.0, 1.2 + 2.2 * len(vehicles)), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(vehicles), 1, sharex=True))
    for ax, vid in zip(axes, vehicles):
        for k, (name, _, label) in enumerate(FLIGHTS):
            rows = data[name].rows_of(vid) if name in data else {}
            if not rows:
                continue
            sigma = 3.0 * np.hypot(rows["sigma_x_m"], rows["sigma_y_m"])
            ax.fill_between(rows["t_s"], 0.0, sigma, color=f"C{k}", alpha=0.15, lw=0)
            ax.plot(rows["t_s"], rows["err_pos_m"], color=f"C{k}", lw=1.0, label=f"{label}: error")
            ax.plot(rows["t_s"], sigma, color=f"C{k}", lw=0.6, ls="--", label=f"{label}: 3-sigma")
        ax.set_ylabel(f"v{vid} position error [m]")
        ax.grid(alpha=0.3)
    axes[0].set_title("GNSS jammed all flight: position error and its 3-sigma bound, SLAM vs dead reckoning")
    axes[0].legend(loc="upper left", fontsize="small", ncols=2)
    axes[-1].set_xlabel("sim time [s]")
    return fig


def nees_comparison(data: dict[str, RunData], bin_s: float = 2.0) -> Figure | None:
    """Pose NEES (3 dof) averaged over the vehicles per ``bin_s``, both flights, with the 3-dof mean."""
    fig = Figure(figsize=(9.0, 3.5), layout="constrained")
    ax = fig.subplots()
    drew = False
    for k, (name, _, label) in enumerate(FLIGHTS):
        m = data[name].metrics if name in data else {}
        if not m:
            continue
        ax.plot(*statistics.binned_mean(m["t_s"], m["nees"], bin_s), color=f"C{k}", lw=1.2, label=label)
        drew = True
    if not drew:
        return None
    ax.axhline(3.0, color="black", lw=0.8, ls=":", label="expected (3 dof)")
    ax.set_yscale("log")
    ax.set_xlabel("sim time [s]")
    ax.set_ylabel("pose NEES")
    ax.set_title(f"pose NEES, mean over vehicles per {bin_s:g} s (one seed: a sample, not a Monte Carlo mean)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize="small")
    return fig
