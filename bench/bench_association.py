"""The cost per camera frame of data association (each method, on the repetitive synthetic scenes of
the association tests) and of visual odometry (SIFT on both 80 px frames, matching, the rigid
RANSAC fit and its covariance, on rendered frames of the procedural terrain). Context rows: no
targets (the issue asks for the costs, side by side)."""

from __future__ import annotations

import time

import numpy as np

from bench.common import Row
from experiments.point_scenes import SceneSpec, scene
from sim.camera import camera_frame
from sim.terrain import procedural_terrain
from vehicle.association.methods import METHODS
from vehicle.vision.features import detect, make_detector
from vehicle.vision.odometry import frame_motion

REPETITIVE = SceneSpec(period_m=1.2, view_m=3.0, pose_sigma_m=0.35)


def association_rows(frames: int) -> list[Row]:
    scenes = [scene(np.random.default_rng(seed), REPETITIVE) for seed in range(frames)]
    rows = []
    for name, method in METHODS.items():
        ms = []
        for seed, s in enumerate(scenes):
            rng = np.random.default_rng(1000 + seed)
            start = time.perf_counter()
            method(s.problem, rng)
            ms.append((time.perf_counter() - start) * 1e3)
        k, n = np.median([s.problem.shape for s in scenes], axis=0)
        details = {
            "frames": frames,
            "p99_ms": round(float(np.percentile(ms, 99)), 3),
            "observations_median": int(k),
            "landmarks_median": int(n),
        }
        rows.append(
            Row("association", name, "time per frame, median", round(float(np.median(ms)), 3), "ms", "-", None, details)
        )
    return rows


def visual_odometry_row(frames: int) -> Row:
    terrain = procedural_terrain(np.random.default_rng(7), size_px=1200, metres_per_pixel=0.1)
    detector = make_detector("sift")
    rng = np.random.default_rng(3)
    ms, failed = [], 0
    for _ in range(frames):
        pose = np.array([rng.uniform(-40, 40), rng.uniform(-40, 40), rng.uniform(-np.pi, np.pi)])
        step = np.array([0.4 * np.cos(pose[2]), 0.4 * np.sin(pose[2]), 0.02])
        first, second = camera_frame(terrain, pose, rng), camera_frame(terrain, pose + step, rng)
        start = time.perf_counter()
        motion = frame_motion(detect(first, detector), detect(second, detector), 80, 0.1, rng)
        ms.append((time.perf_counter() - start) * 1e3)
        failed += int(not hasattr(motion, "delta"))
    details = {"frames": frames, "p99_ms": round(float(np.percentile(ms, 99)), 3), "no_motion": failed}
    return Row(
        "visual_odometry",
        "80 px frames, SIFT",
        "time per frame pair, median",
        round(float(np.median(ms)), 3),
        "ms",
        "-",
        None,
        details,
    )


def run(quick: bool = False) -> list[Row]:
    return [*association_rows(20 if quick else 100), visual_odometry_row(20 if quick else 200)]
