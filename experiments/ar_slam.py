"""`swarm experiment ar-slam`: the AR-EKF-SLAM paper's experiment on the simulator. One camera UAV
flies a long GNSS-denied circle (at least 1600 frames, like the paper's 1605) over the terrain, from a
surveyed start; the same flight (same seed: the same frames, noise and all) is estimated by:

- ``ekf-slam``: every landmark stays in the state (a fixed range that never lets one go);
- ``fixed 25 m``: the paper's baseline, ar-ekf-slam held at R = 25 m (it never adapts);
- ``ar-ekf-slam``: the adaptive local map, with each association method (descriptor, nn, jcbb, aco);
- ``ar-ekf-slam, visual odometry``: the same with no wheels (speed and yaw rate from the camera);
- the association methods again over repetitive ground (``world.terrain_period_px``), where
  look-alikes a period away make association hard.

Each estimator runs in this process on the stream a vehicle process would receive
(``harness.vehicle_feed``), through the vehicle's fusion horizon and (for visual odometry) its VO
front end, as in the vehicle process; its time per camera frame (front end included, the paper's
figure 7) is measured alone. The world's truth scores what the vehicle never sees: the squared x error over
time (figure 8), position RMSE, pose NEES, the state's size, and each association: a pair is correct
when the keypoint and the landmark are the same ground point (within ``SAME_POINT_M``), the truth of a
landmark being the ground point of the keypoint that created it. Writes experiment.json and figures.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bus import messages as m
from bus import statistics
from bus.config import SwarmConfig, build_config
from bus.errors import ConfigError
from bus.topics import Topic
from experiments.ar_slam_figures import write_figures
from experiments.ar_slam_track import Track
from experiments.conclusions import write_experiment
from launch.runspec import RunSpec
from vehicle.association.optimum import optimal_assignment
from vehicle.association.problem import linear_cost
from vehicle.vision import features

SURVEYED_START = {"prior_sigma_m": 0.1, "prior_heading_sigma_rad": 0.005}
SAME_POINT_M = 0.3  # a keypoint and a landmark this close on the ground are the same point
PERIOD_US = 20_000
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
                "cooperative": False,
                "association": case.association,
                "odometry": case.odometry,
                "ar": case.ar,
            },
            "faults": [{"kind": "jam-gnss", "center_m": [0, 0], "radius_m": 100_000}],
        }
    )


class _Timed:
    """The estimator as the fusion horizon sees it, timing and scoring each camera frame once."""

    def __init__(self, f, on_frame) -> None:
        self.f, self.on_frame, self.done = f, on_frame, set()

    def handle(self, msg) -> None:
        if not isinstance(msg, m.CameraFrame) or (msg.stamp_us, msg.seq) in self.done:
            self.f.handle(msg)
            return
        before = self.f.state.counters.landmarks if self.f.initialized else 0
        start = time.perf_counter()
        self.f.handle(msg)
        self.done.add((msg.stamp_us, msg.seq))
        self.on_frame(msg, (time.perf_counter() - start) * 1e3, before)

    def handle_row(self, *sample) -> None:
        self.f.handle_row(*sample)

    def cycle(self, t_us: int) -> None:
        self.f.cycle(t_us)

    def snapshot(self):
        return self.f.snapshot()

    def restore(self, snapshot) -> None:
        self.f.restore(snapshot)


def fly(case: Case, *, seed: int, duration_s: float) -> Track:
    """Estimate one flight (module docstring)."""
    from experiments.harness import vehicle_feed
    from sim.world import World
    from vehicle.estimators import get_estimator
    from vehicle.process.fusion import FusionHorizon
    from vehicle.vision.visual_odometry import ANNOUNCE_OFFSET_US, VisualOdometry

    config = ar_slam_config(case, seed=seed, duration_s=duration_s)
    feed = vehicle_feed(config)
    world = World(config).advance(round(duration_s * 1e6))
    truth = {stamp: rows[0][:3] for stamp, rows in zip(world.truth_stamps, world.truth)}
    f = get_estimator(config.for_vehicle(), 1)
    landmark_truth: dict[bytes, np.ndarray] = {}
    track = Track()

    def on_frame(msg, ms: float, landmarks_before: int) -> None:
        track.frame_ms.append(ms)
        if f.sightings is not None and f.initialized and msg.stamp_us in truth:
            _score_frame(track, f, f.sightings, msg, truth[msg.stamp_us], landmark_truth, landmarks_before)

    fusion = FusionHorizon(_Timed(f, on_frame), horizon_us=round(config.vehicle.fusion_horizon_s * 1e6), every_cycles=0)
    vo = VisualOdometry(1, detector=config.vehicle.features, reject=lambda *_: None)
    visual = config.vehicle.visual_odometry(1)
    t_us = 0
    for topic, msg in feed:
        while t_us < msg.stamp_us:
            fusion.cycle(t_us)
            if t_us % 1_000_000 == 0 and f.initialized and t_us in truth:
                _score_pose(track, f, truth[t_us], t_us)
            t_us += PERIOD_US
        if visual and topic is Topic.ODOM:
            continue
        if visual and topic is Topic.CAMERA:
            for motion in vo.on_frame(msg):
                fusion.push(Topic.ODOM, motion)
            fusion.push(topic, msg)
            fusion.expect(msg.stamp_us + ANNOUNCE_OFFSET_US)
            continue
        fusion.push(topic, msg)
    track.vo_failures = vo.failures
    return track


def _score_pose(track: Track, f, true_pose: np.ndarray, t_us: int) -> None:
    e = statistics.pose_error(f.x[:3], true_pose)
    track.t_s.append(t_us * 1e-6)
    track.x_error_m2.append(float(e[0] ** 2))
    track.error_m.append(float(np.hypot(e[0], e[1])))
    track.nees.append(statistics.nees(e, f.P[:3, :3]))
    track.state_dim.append(len(f.x))


def _score_frame(track: Track, f, the_map, msg, true_pose, landmark_truth: dict, landmarks_before: int) -> None:
    """The frame's pairs against the truth; then the truth of the landmarks it created."""
    cached = the_map.front_end.remembered(msg.stamp_us, msg.seq)
    if cached is None:
        return
    found = cached[0]
    size, scale = msg.pixels.shape[0], msg.metres_per_pixel
    ground = features.body_to_world(true_pose, features.range_bearing(found.points_px, size, scale))
    descriptors = f.state.landmarks.descriptors
    if descriptors is None:
        return
    known = [landmark_truth.get(d.tobytes()) for d in descriptors]
    known_xy = np.array([k if k is not None else (np.inf, np.inf) for k in known]).reshape(-1, 2)
    pairs = the_map.last_pairs
    track.pairs += len(pairs)
    for i, j in pairs:
        if j < len(known_xy) and np.hypot(*(ground[i] - known_xy[j])) < SAME_POINT_M:
            track.correct += 1
    if len(known_xy):
        nearest = np.min(np.hypot(*(ground[:, None, :] - known_xy[None, :, :]).transpose(2, 0, 1)), axis=1)
        track.opportunities += int(np.sum(nearest < SAME_POINT_M))
    problem = getattr(the_map, "last_problem", None)
    if problem is not None and problem[0].shape[0]:
        p, assignment = problem
        track.gap.append(linear_cost(p, assignment) - linear_cost(p, optimal_assignment(p)))
    added = f.state.counters.landmarks - landmarks_before
    if added > 0:
        by_descriptor = {d.tobytes(): i for i, d in enumerate(found.descriptors)}
        for d in descriptors[-added:]:
            i = by_descriptor.get(d.tobytes())
            if i is not None:
                landmark_truth[d.tobytes()] = ground[i]


def summary(track: Track) -> dict[str, Any]:
    frame = np.array(track.frame_ms)
    low, high = statistics.chi2_band(statistics.POSE_NEES_DOF, runs=1)
    nees = np.array(track.nees)
    return {
        "frames": len(frame),
        "rmse_m": round(float(np.sqrt(np.mean(np.square(track.error_m)))), 3),
        "final_error_m": round(track.error_m[-1], 3) if track.error_m else None,
        "anees": round(float(np.mean(nees)), 2),
        "nees_inside_95": round(float(np.mean((nees >= low) & (nees <= high))), 3),
        "state_dim_max": int(max(track.state_dim)),
        "state_dim_final": int(track.state_dim[-1]),
        "frame_ms_p50": round(float(np.percentile(frame, 50)), 2),
        "frame_ms_p99": round(float(np.percentile(frame, 99)), 2),
        "frame_ms_last_tenth_p50": round(float(np.percentile(frame[-len(frame) // 10 :], 50)), 2),
        "pairs": track.pairs,
        "correct_pairs": track.correct,
        "false_pairs": track.pairs - track.correct,
        "correct_rate": round(track.correct / track.opportunities, 3) if track.opportunities else None,
        "gap_to_optimum_mean": round(float(np.mean(track.gap)), 2) if track.gap else None,
        "vo_failures": track.vo_failures,
    }


def _range_of(case: Case) -> str:
    if case.estimator != "ar-ekf-slam":
        return "all"
    return "fixed 25 m" if case.ar == FIXED_RANGE else "adaptive"


def slug(case: Case) -> str:
    """The run directory's name of a case."""
    return case.name.replace(" ", "-")


def plan(seed: int, duration: float, cases: str) -> list[RunSpec]:
    """One run per case (default: every case) on ``seed``, each an estimator fed in one process
    (``fly_case``)."""
    return [
        RunSpec(
            slug(case),
            case.name,
            seed,
            ar_slam_config(case, seed=seed, duration_s=duration).model_dump(mode="json"),
            measure=f"{__name__}:measure",
            runner=f"{__name__}:fly_case",
        )
        for case in chosen_cases(cases)
    ]


def chosen_cases(text: str) -> tuple[Case, ...]:
    """The cases a comma-separated list names (every case for none); ConfigError naming the unknown."""
    chosen = [c.strip() for c in text.split(",") if c.strip()]
    known = {c.name: c for c in CASES}
    unknown = [c for c in chosen if c not in known]
    if unknown:
        raise ConfigError(f"unknown case(s) {', '.join(unknown)}; known: {', '.join(known)}")
    return tuple(known[c] for c in chosen) if chosen else CASES


def fly_case(spec: RunSpec, config: SwarmConfig, run_dir: Path) -> list[str]:
    """Fly one case in this process: its track (track.json) and its row of the table (case.json)."""
    case = next(c for c in CASES if c.name == spec.variant)
    track = fly(case, seed=spec.seed, duration_s=config.clock.duration_s)
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
    tracks = {}
    for case in chosen_cases(cases):
        if slug(case) in done:
            table["cases"][case.name] = json.loads((folder / slug(case) / CASE).read_text())
            tracks[case.name] = Track(**json.loads((folder / slug(case) / TRACK).read_text()))
    write_experiment(folder, table)
    lines = [
        f"  {name:<28} RMSE {row['rmse_m']} m  ANEES {row['anees']}  state <= {row['state_dim_max']}"
        f"  frame p50/p99 {row['frame_ms_p50']}/{row['frame_ms_p99']} ms  correct {row['correct_rate']}"
        f"  false {row['false_pairs']}"
        for name, row in table["cases"].items()
    ]
    return lines + [f"figure: {figure}" for figure in write_figures(folder, tracks)]
