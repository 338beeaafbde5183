"""`swarm experiment ar-slam`: the AR-EKF-SLAM paper's experiment on the simulator. One camera UAV
flies a long GNSS-denied circle (at least 1600 frames, like the paper's 1605) over the terrain, from a
surveyed start; the same flight (same seed: the same frames, noise and all) is estimated by:

- ``ekf-slam``: every landmark stays in the state (a fixed range that never lets one go);
- ``fixed 25 m``: the paper's baseline, ar-ekf-slam held at R = 25 m (it never adapts);
- ``ar-ekf-slam``: the adaptive local map, with each association method (descriptor, nn, jcbb, aco);
- ``ar-ekf-slam, visual odometry``: the same with no wheels (speed and yaw rate from the camera);
- the association methods again over repetitive ground (``world.terrain_period_px``), where
  look-alikes a period away make association hard;
- the paper's own 3-D system (experiments.ar_slam3d_cases): a flight over relief estimated by the
  6 + 3n back end with the adaptive range, a fixed 25 m range and no range (full 3-D EKF-SLAM).

Each estimator runs in this process on the stream a vehicle process would receive
(``harness.vehicle_feed``), through the vehicle's fusion horizon and (for visual odometry) its VO
front end, as in the vehicle process; its time per camera frame (front end included, the paper's
figure 7) is measured alone. The world's truth scores what the vehicle never sees: the squared x error over
time (figure 8), position RMSE, pose NEES, the state's size, and each association: a pair is correct
when the keypoint and the landmark are the same ground point (within ``ar_slam_track.SAME_POINT_M``), the truth of a
landmark being the ground point of the keypoint that created it. Writes experiment.json and figures.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from bus.config import SwarmConfig, build_config
from bus.errors import ConfigError
from experiments import ar_slam3d_cases
from experiments.ar_slam_figures import write_figures
from experiments.ar_slam_track import Track, fly, summary
from experiments.conclusions import write_experiment
from launch.runspec import RunSpec

SURVEYED_START = {"prior_sigma_m": 0.1, "prior_heading_sigma_rad": 0.005}
REPETITIVE_PERIOD_PX = 16  # 1.6 m tiles


FIXED_RANGE = {"r0_m": 25.0, "r_max_m": 25.0, "n_min": 1, "n_max": 100_000}  # R never leaves 25 m
SPEED_MPS = 4.0  # the world's default speed: 1630 frames over 652 m (the paper: 1605 over 820 m)
DURATION_S = 163.0
TRACK, CASE = "track.json", "case.json"  # what a case's run directory holds


@dataclass(frozen=True)
class Case:
    name: str
    estimator: str
    association: str = "descriptor"
    period_px: int = 0
    odometry: str = "wheel"
    ar: dict = field(default_factory=dict)


CASES = (
    Case("ekf-slam", "ekf-slam"),
    Case("fixed 25 m", "ar-ekf-slam", ar=FIXED_RANGE),
    Case("ar-ekf-slam", "ar-ekf-slam"),
    Case("ar-ekf-slam visual odometry", "ar-ekf-slam", odometry="visual"),
    Case("ar-ekf-slam nn", "ar-ekf-slam", "nn"),
    Case("ar-ekf-slam jcbb", "ar-ekf-slam", "jcbb"),
    Case("ar-ekf-slam aco", "ar-ekf-slam", "aco"),
    *(Case(f"repetitive {a}", "ar-ekf-slam", a, REPETITIVE_PERIOD_PX) for a in ("descriptor", "nn", "jcbb", "aco")),
)


def ar_slam_config(case: Case, *, seed: int, duration_s: float) -> SwarmConfig:
    """One camera UAV on a circle of 40 m, GNSS jammed everywhere, no cooperation."""
    return build_config(
        {
            "name": case.name.replace(" ", "-"),
            "world": {
                "vehicles": 1,
                "seed": seed,
                "trajectories": ["circle"],
                "radius_m": 40.0,
                "speed_mps": SPEED_MPS,
                "terrain_period_px": case.period_px,
            },
            "clock": {"duration_s": duration_s},
            "sensors": {"camera_rate_hz": 10, **SURVEYED_START},
            "vehicle": {
                "estimator": case.estimator,
                "cooperation": {"enabled": False},
                "association": case.association,
                "odometry": case.odometry,
                "ar": case.ar,
            },
            "faults": [{"kind": "jam-gnss", "center_m": [0, 0], "radius_m": 100_000}],
        }
    )


def _range_of(case: Case) -> str:
    if case.estimator != "ar-ekf-slam":
        return "all"
    return "fixed 25 m" if case.ar == FIXED_RANGE else "adaptive"


def slug(case: Case) -> str:
    """The run directory's name of a case."""
    return case.name.replace(" ", "-")


def plan(seed: int, duration: float, cases: str) -> list[RunSpec]:
    """One run per case (default: every case) on ``seed``, each an estimator fed in one process
    (``fly_case``; the 3-D cases' ``ar_slam3d_cases.fly_case``)."""
    cases_2d, cases_3d = chosen_cases(cases)
    return [
        *(
            RunSpec(
                slug(case),
                case.name,
                seed,
                ar_slam_config(case, seed=seed, duration_s=duration).model_dump(mode="json"),
                measure=f"{__name__}:measure",
                runner=f"{__name__}:fly_case",
            )
            for case in cases_2d
        ),
        *(ar_slam3d_cases.spec(name, seed, duration, _camera_uav(seed, duration)) for name in cases_3d),
    ]


def _camera_uav(seed: int, duration: float) -> dict[str, Any]:
    """The configuration a 3-D case's run keeps for the campaign's table (its flight is the back end's)."""
    adaptive = next(case for case in CASES if case.name == "ar-ekf-slam")
    return ar_slam_config(adaptive, seed=seed, duration_s=duration).model_dump(mode="json")


def chosen_cases(text: str) -> tuple[tuple[Case, ...], tuple[str, ...]]:
    """The 2-D cases and the 3-D cases (names of ``ar_slam3d_cases.CASES``) a comma-separated list
    names (for none: every 2-D case and ``ar_slam3d_cases.DEFAULT``); ConfigError naming the unknown."""
    chosen = [c.strip() for c in text.split(",") if c.strip()]
    known = {c.name: c for c in CASES}
    unknown = [c for c in chosen if c not in known and c not in ar_slam3d_cases.CASES]
    if unknown:
        raise ConfigError(f"unknown case(s) {', '.join(unknown)}; known: {', '.join([*known, *ar_slam3d_cases.CASES])}")
    if not chosen:
        return CASES, ar_slam3d_cases.DEFAULT
    return tuple(known[c] for c in chosen if c in known), tuple(c for c in chosen if c in ar_slam3d_cases.CASES)


def fly_case(spec: RunSpec, config: SwarmConfig, run_dir: Path) -> list[str]:
    """Fly one case in this process: its track (track.json) and its row of the table (case.json)."""
    case = next(c for c in CASES if c.name == spec.variant)
    track = fly(ar_slam_config(case, seed=spec.seed, duration_s=config.clock.duration_s))
    (run_dir / TRACK).write_text(json.dumps(asdict(track)) + "\n")
    (run_dir / CASE).write_text(json.dumps(case_row(case, track), indent=2, sort_keys=True) + "\n")
    return []


def measure(run_dir: Path) -> dict[str, Any]:
    """A case's numbers for the campaign's results table."""
    row = json.loads((run_dir / CASE).read_text())
    keys = ("rmse_m", "anees", "state_dim_max", "frame_ms_p50", "frame_ms_p99", "correct_rate", "false_pairs")
    return {key: row[key] for key in keys}


def case_row(case: Case, track: Track) -> dict[str, Any]:
    return {
        "estimator": case.estimator,
        "association": case.association,
        "odometry": case.odometry,
        "range": _range_of(case),
        "terrain": "repetitive" if case.period_px else "varied",
        **summary(track),
    }


def conclude(rows: list[dict], folder: Path, *, seed: int, duration: float, cases: str) -> list[str]:
    """experiment.json (a row per case that completed) and the figures, from the cases' run directories."""
    done = {row["run"] for row in rows if row.get("status") == "complete"}
    table: dict[str, Any] = {"seed": seed, "duration_s": duration, "cases": {}}
    tracks, tracks_3d = {}, {}
    cases_2d, cases_3d = chosen_cases(cases)
    for case in cases_2d:
        if slug(case) in done:
            table["cases"][case.name] = json.loads((folder / slug(case) / CASE).read_text())
            tracks[case.name] = Track(**json.loads((folder / slug(case) / TRACK).read_text()))
    for name in cases_3d:
        run_dir = folder / ar_slam3d_cases.slug(name)
        if ar_slam3d_cases.slug(name) in done:
            table["cases"][name] = json.loads((run_dir / ar_slam3d_cases.CASE).read_text())
            tracks_3d[name] = ar_slam3d_cases.load_track(run_dir)
    write_experiment(folder, table)
    lines = [
        f"  {name:<28} RMSE {row['rmse_m']} m  ANEES {row['anees']}  state <= {row['state_dim_max']}"
        f"  frame p50/p99 {row['frame_ms_p50']}/{row['frame_ms_p99']} ms"
        + (f"  correct {row['correct_rate']}  false {row['false_pairs']}" if row["correct_rate"] is not None else "")
        for name, row in table["cases"].items()
    ]
    figures = [*(write_figures(folder, tracks) if tracks else []), *ar_slam3d_cases.write_figures(folder, tracks_3d)]
    return lines + [f"figure: {figure}" for figure in figures]
