"""Synthetic association scenes: a mapped set of point landmarks, a pose estimate off the truth by a
draw of its own covariance, and one frame of range-bearing observations of the landmarks in view
plus clutter (points the map does not hold), with the true assignment that only the world knows.
``period_m`` lays the landmarks on a jittered square grid: repetitive ground, where every landmark
has look-alikes one period away. Pure; an explicit seeded generator."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.association.problem import UNPAIRED, Problem, problem
from vehicle.models import landmarks as slam


@dataclass(frozen=True)
class SceneSpec:
    period_m: float = 1.0  # grid spacing of the landmarks
    jitter_m: float = 0.15  # uniform offset of each landmark from its grid node
    view_m: float = 4.0  # observations within this range of the true pose
    pose_sigma_m: float = 0.3
    heading_sigma_rad: float = 0.03
    landmark_sigma_m: float = 0.05  # mapped landmark error
    range_sigma_m: float = 0.05
    bearing_sigma_rad: float = 0.01
    seen_probability: float = 0.8
    clutter: int = 4
    gate_probability: float = 0.99


@dataclass(frozen=True)
class Scene:
    problem: Problem
    truth: np.ndarray  # (k,) the true landmark of each observation, -1 for clutter


def scene(rng: np.random.Generator, spec: SceneSpec = SceneSpec()) -> Scene:
    """One frame (module docstring): the estimate at the origin heading east."""
    half = spec.view_m + 3 * spec.pose_sigma_m
    grid = np.arange(-half, half + 1e-9, spec.period_m)
    true_xy = np.array([(x, y) for x in grid for y in grid]) + rng.uniform(
        -spec.jitter_m, spec.jitter_m, (len(grid) ** 2, 2)
    )
    mapped_xy = true_xy + rng.normal(0.0, spec.landmark_sigma_m, true_xy.shape)
    P_pose = np.diag([spec.pose_sigma_m**2, spec.pose_sigma_m**2, spec.heading_sigma_rad**2])
    estimate = np.zeros(3)
    pose = estimate + rng.multivariate_normal(np.zeros(3), P_pose)
    d = true_xy - pose[:2]
    seen = np.flatnonzero(
        (np.hypot(d[:, 0], d[:, 1]) <= spec.view_m) & (rng.uniform(size=len(true_xy)) < spec.seen_probability)
    )
    clutter_xy = pose[:2] + rng.uniform(-spec.view_m, spec.view_m, (spec.clutter, 2)) * 0.7
    points = np.vstack([true_xy[seen], clutter_xy])
    truth = np.concatenate([seen, np.full(spec.clutter, UNPAIRED)])
    shuffle = rng.permutation(len(points))
    points, truth = points[shuffle], truth[shuffle]
    z = np.stack([np.hypot(*(points - pose[:2]).T), np.arctan2(*(points - pose[:2]).T[::-1]) - pose[2]], axis=1)
    z += rng.normal(0.0, [spec.range_sigma_m, spec.bearing_sigma_rad], z.shape)
    R = np.tile(np.diag([spec.range_sigma_m**2, spec.bearing_sigma_rad**2]), (len(z), 1, 1))
    x = np.concatenate([estimate, mapped_xy.ravel()])
    candidates = np.flatnonzero(np.hypot(*mapped_xy.T) <= spec.view_m + 3 * spec.pose_sigma_m)
    predicted, C = predictions(x, P_pose, spec.landmark_sigma_m, candidates)
    p = problem(z, R, predicted, C, gate_probability=spec.gate_probability)
    index_of = {int(j): a for a, j in enumerate(candidates)}
    local_truth = np.array([index_of.get(int(t), UNPAIRED) if t >= 0 else UNPAIRED for t in truth], dtype=np.int64)
    return Scene(p, local_truth)


def predictions(
    x: np.ndarray, P_pose: np.ndarray, landmark_sigma_m: float, rows: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted observations (m, 2) of landmarks ``rows`` and their joint covariance (2m, 2m), the
    landmarks independent of the pose and of each other."""
    m = len(rows)
    predicted = np.zeros((m, 2))
    H = np.zeros((2 * m, 3 + 2 * m))
    for a, j in enumerate(rows.tolist()):
        predicted[a], H[2 * a : 2 * a + 2, :3], H[2 * a : 2 * a + 2, 3 + 2 * a : 5 + 2 * a] = slam.observe(x, 3, j)
    P = np.zeros((3 + 2 * m, 3 + 2 * m))
    P[:3, :3] = P_pose
    P[3:, 3:] = np.eye(2 * m) * landmark_sigma_m**2
    return predicted, H @ P @ H.T


def correct_rate(assignment: np.ndarray, truth: np.ndarray) -> tuple[float, int]:
    """Share of the true pairs found, and the false pairs made (paired to a wrong landmark, or clutter paired)."""
    real = truth >= 0
    found = float(np.mean(assignment[real] == truth[real])) if real.any() else 1.0
    false = int(np.sum((assignment >= 0) & (assignment != truth)))
    return found, false
