"""The 3-D cases of `swarm experiment ar-slam`: the paper's own system (its 6 + 3n back end,
experiments.ar_slam3d) on one flight over terrain with relief, 10 frames a second for the
experiment's duration (163 s: 1,630 frames over about 815 m; the paper: 1,605 over about 820 m),
estimated with the adaptive range, a fixed 25 m range and no range (full 3-D EKF-SLAM), and (when
named) the adaptive range on a flat-ground map (each frame's points placed on a plane below the
camera, as a 2-D map would: experiments.flat_ground) instead of triangulated. The same
seed gives every case the same flight, landmarks and pixel noise. Points are associated by landmark
id (the back end alone: full EKF-SLAM's association over a thousand landmarks per frame would cost
more than the comparison is worth; the Monte Carlo of docs/ar-slam.md measures nn association).

Each case is a run of its own in one process (``fly_case``): its track (track3d.npz) and its row of
the table (case.json, the same keys as the 2-D cases' where they mean the same; the association's
correct rate and false pairs are None, association being by id) and, as a swarm run has, run.mcap
and a Lichtblick layout: the flight, the map and its ellipsoids (experiments.ar_slam3d_recording).
``conclude`` adds the paper's figures 7 and 8 for the cases that completed.
"""

from __future__ import annotations

import json
from dataclasses import asdict, fields
from pathlib import Path
from typing import Any

import numpy as np

from experiments.ar_slam3d import RATE_HZ, Track, fly, world
from experiments.ar_slam3d_figures import figure_time, figure_track, summary
from experiments.ar_slam3d_recording import FlightRecording
from launch.runspec import RunSpec
from vehicle.models import slam3d

CASES = {  # each case's flight: the back end's range (experiments.ar_slam3d.MODES) and where the map's points come from
    "3-D ar-ekf-slam": {"mode": "adaptive"},
    "3-D fixed 25 m": {"mode": "fixed-25"},
    "3-D ekf-slam": {"mode": "full"},
    "3-D flat-ground map": {
        "mode": "adaptive",
        "flat_ground": True,
    },  # on a plane below the camera (experiments.flat_ground)
}
# flown when no case is named: full 3-D EKF-SLAM keeps every landmark (700 after 600 frames, 154 s on
# this machine, its cost per frame growing as their square), so over the default 1,630 frames it would
# take hours; it is flown when named (docs/ar-slam.md)
DEFAULT = ("3-D ar-ekf-slam", "3-D fixed 25 m")
TRACK, CASE = "track3d.npz", "case.json"
FIGURES = ("frame_time_3d.png", "track_3d.png")


def slug(name: str) -> str:
    return name.replace(" ", "-")


def spec(name: str, seed: int, duration_s: float, config: dict[str, Any]) -> RunSpec:
    """The run of the 3-D case ``name`` (of CASES); ``config``: the experiment's configuration of a
    camera UAV, kept for the campaign's table (the flight itself is the back end's, not the world's)."""
    config = {**config, "name": slug(name), "clock": {**config.get("clock", {}), "duration_s": duration_s}}
    return RunSpec(slug(name), name, seed, config, measure=f"{__name__}:measure", runner=f"{__name__}:fly_case")


def frames_of(duration_s: float) -> int:
    return max(1, round(duration_s * RATE_HZ))


def fly_case(spec: RunSpec, config, run_dir: Path) -> list[str]:
    """Fly one 3-D case in this process: its track, its row of the table and, unless the run records
    nothing (``--no-record``), its run.mcap with a Lichtblick layout (experiments.ar_slam3d_recording)."""
    frames = frames_of(config.clock.duration_s)
    recording = FlightRecording(run_dir, world(spec.seed, frames + 1)[1]) if config.view.record else None
    try:
        track = fly(spec.seed, frames, **CASES[spec.variant], on_frame=None if recording is None else recording.frame)
    finally:
        if recording is not None:
            recording.close()
    np.savez_compressed(run_dir / TRACK, **asdict(track))
    (run_dir / CASE).write_text(json.dumps(case_row(spec.variant, track), indent=2, sort_keys=True) + "\n")
    return []


def case_row(name: str, track: Track) -> dict[str, Any]:
    row, case = summary(track), CASES[name]
    return {
        "estimator": "ar-slam-3d back end",
        "association": "by id",
        "odometry": "visual odometry's rotation (given); points on flat ground"
        if case.get("flat_ground")
        else "visual odometry's rotation and baseline (given)",
        "range": {"adaptive": "adaptive", "fixed-25": "fixed 25 m", "full": "all"}[case["mode"]],
        "terrain": "relief",
        "anees": row["position_anees"],
        "state_dim_max": slam3d.HEAD + slam3d.POINT * row["landmarks_max"],
        "correct_rate": None,
        "false_pairs": None,
        **row,
    }


def measure(run_dir: Path) -> dict[str, Any]:
    row = json.loads((run_dir / CASE).read_text())
    keys = ("rmse_m", "anees", "state_dim_max", "frame_ms_p50", "frame_ms_p99", "correct_rate", "false_pairs")
    return {key: row[key] for key in keys}


def load_track(run_dir: Path) -> Track:
    with np.load(run_dir / TRACK) as data:
        return Track(**{f.name: data[f.name] for f in fields(Track)})


def write_figures(folder: Path, tracks: dict[str, Track]) -> list[Path]:
    """The paper's figures 7 and 8 of the 3-D cases that completed (none without any)."""
    if not tracks:
        return []
    paths = [folder / name for name in FIGURES]
    figure_time(tracks, paths[0])
    figure_track(tracks, paths[1])
    return paths
