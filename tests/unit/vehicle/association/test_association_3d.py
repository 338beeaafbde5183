"""Data association on 3-D observations (the AR-EKF-SLAM paper's triangulated body-frame points): the
same problem and methods as in 2-D, of dimension 3 and with no angle to wrap. The joint test grown
pair by pair equals the batch one; the paper's tie-break ln|S|; on a repetitive 3-D grid seen with the
pose off by a draw of its own covariance, joint compatibility and the ant colony pair more landmarks
rightly than nearest neighbour."""

from __future__ import annotations

import numpy as np
import pytest

from tests.unit.vehicle.association.oracle import grown_as_batch
from vehicle.association.methods import METHODS
from vehicle.association.problem import problem


def grid_scene(rng: np.random.Generator, *, period_m: float, pose_sigma_m: float, clutter: int = 3):
    """A jittered 3-D grid of landmarks within 6 m, seen from a pose off by a draw of its covariance:
    the problem (angles none) and the true landmark of each observation (-1: clutter)."""
    axis = np.arange(-6.0, 6.01, period_m)
    X = np.stack(np.meshgrid(axis, axis, axis[: max(2, len(axis) // 3)]), -1).reshape(-1, 3)
    X = X + rng.uniform(-0.1, 0.1, X.shape) * period_m
    yaw = rng.uniform(-np.pi, np.pi)
    R = np.array([[np.cos(yaw), -np.sin(yaw), 0.0], [np.sin(yaw), np.cos(yaw), 0.0], [0.0, 0.0, 1.0]])
    P_pose = pose_sigma_m**2 * np.eye(3)
    p_true = np.zeros(3)
    p_hat = p_true + rng.multivariate_normal(np.zeros(3), P_pose)
    m = len(X)
    landmark_var = 0.02**2
    C = np.kron(np.ones((m, m)), R.T @ P_pose @ R) + landmark_var * np.eye(3 * m)
    predicted = (X - p_hat) @ R
    seen = rng.choice(m, size=min(m, 15), replace=False)
    noise = 0.03**2 * np.eye(3)
    z = (X[seen] - p_true) @ R + rng.multivariate_normal(np.zeros(3), noise, len(seen))
    z = np.vstack([z, rng.uniform(-6, 6, (clutter, 3))])
    truth = np.concatenate([seen, np.full(clutter, -1)])
    Rz = np.repeat(noise[None], len(z), axis=0)
    return problem(z, Rz, predicted, C, angles=()), truth


def test_the_3d_joint_test_grown_pair_by_pair_is_the_batch_one():
    p, truth = grid_scene(np.random.default_rng(0), period_m=3.0, pose_sigma_m=0.2)
    assert p.dim == 3
    assert grown_as_batch(p, np.where(truth >= 0, truth, -1)).compatible(p)


def test_nearest_neighbour_breaks_3d_ties_by_the_smaller_innovation_covariance():
    C = np.diag([0.5, 0.5, 0.5, 0.05, 0.05, 0.05])
    predicted = np.array([[5.0 - np.sqrt(0.5), 0.0, 1.0], [5.0 - np.sqrt(0.05), 0.0, 1.0]])
    p = problem(np.array([[5.0, 0.0, 1.0]]), 1e-9 * np.eye(3)[None], predicted, C, angles=())
    assert p.d2[0, 0] == pytest.approx(p.d2[0, 1])
    assert METHODS["nn"](p, np.random.default_rng(0)).tolist() == [1]


def test_on_a_repetitive_3d_grid_jcbb_and_the_ant_colony_beat_nearest_neighbour():
    right = {name: 0 for name in ("nn", "jcbb", "aco")}
    for run in range(20):
        p, truth = grid_scene(np.random.default_rng(100 + run), period_m=1.0, pose_sigma_m=0.3)
        for name in right:
            assignment = METHODS[name](p, np.random.default_rng(run))
            right[name] += int(np.sum((assignment == truth) & (truth >= 0)))
    assert right["jcbb"] > right["nn"] and right["aco"] > right["nn"], right
