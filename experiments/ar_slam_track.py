"""One flight of the ar-slam experiment (experiments.ar_slam): its estimator fed in this process, timed
per camera frame and scored against the world's truth, and what it did (``Track``), as the figures
(experiments.ar_slam_figures) and the table read it."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bus import messages as m
from bus import statistics
from bus.config import SwarmConfig
from bus.topics import Topic
from vehicle.association.optimum import optimal_assignment
from vehicle.association.problem import linear_cost
from vehicle.vision import features

SAME_POINT_M = 0.3  # a keypoint and a landmark this close on the ground are the same point
PERIOD_US = 20_000


@dataclass
class Track:
    """What one estimator did over the flight: per second (t_s, squared x error, position error,
    pose NEES, state size) and per camera frame (time [ms], association counts)."""

    t_s: list[float] = field(default_factory=list)
    x_error_m2: list[float] = field(default_factory=list)
    error_m: list[float] = field(default_factory=list)
    nees: list[float] = field(default_factory=list)
    state_dim: list[int] = field(default_factory=list)
    frame_ms: list[float] = field(default_factory=list)
    pairs: int = 0
    correct: int = 0
    opportunities: int = 0
    gap: list[float] = field(default_factory=list)
    vo_failures: int = 0


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


def fly(config: SwarmConfig) -> Track:
    """Estimate one flight of ``config`` (experiments.ar_slam's module docstring)."""
    from experiments.harness import vehicle_feed
    from sim.world import World
    from vehicle.estimators import get_estimator
    from vehicle.process.fusion import FusionHorizon
    from vehicle.vision.visual_odometry import ANNOUNCE_OFFSET_US, VisualOdometry

    feed = vehicle_feed(config)
    world = World(config).advance(round(config.clock.duration_s * 1e6))
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
