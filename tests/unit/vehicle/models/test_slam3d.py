"""The paper's 3-D EKF-SLAM model (vehicle.models.slam3d): Jacobians and the initialisation's blocks
against finite differences and linear propagation, and the filter's consistency over 30 seeded flights
over terrain with relief (landmarks at height, each seen as a triangulated body-frame point with a
long, thin covariance along its line of sight), position (3 dof) and full vehicle (6 dof) NEES inside
the two-sided chi-square band at each checkpoint."""

from __future__ import annotations

import numpy as np

from bus.statistics import chi2_band
from vehicle.models import slam3d
from vehicle.models.kalman import gated_update


def yaw_rotation(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_the_observation_and_initialisation_jacobians_match_finite_differences():
    rng = np.random.default_rng(0)
    x = rng.normal(0, 5, slam3d.HEAD + 3 * slam3d.POINT)
    R = yaw_rotation(0.7) @ np.array([[1, 0, 0], [0, np.cos(0.2), -np.sin(0.2)], [0, np.sin(0.2), np.cos(0.2)]])
    h, H = slam3d.observe(x, 1, R)
    step = 1e-6
    numeric = np.column_stack([(slam3d.observe(x + step * e, 1, R)[0] - h) / step for e in np.eye(len(x))])
    np.testing.assert_allclose(H, numeric, atol=1e-6)
    z = rng.normal(0, 3, 3)
    g, grad_x, grad_z = slam3d.initial_point(x, z, R)
    numeric_x = np.column_stack([(slam3d.initial_point(x + step * e, z, R)[0] - g) / step for e in np.eye(len(x))[:6]])
    numeric_z = np.column_stack([(slam3d.initial_point(x, z + step * e, R)[0] - g) / step for e in np.eye(3)])
    np.testing.assert_allclose(grad_x, numeric_x, atol=1e-6)
    np.testing.assert_allclose(grad_z, numeric_z, atol=1e-6)


def test_a_new_landmark_s_covariance_is_the_linear_propagation_of_the_state_and_the_observation():
    rng = np.random.default_rng(1)
    n = slam3d.HEAD + 2 * slam3d.POINT
    A = rng.normal(size=(n, n))
    P = A @ A.T + np.eye(n)
    x, z, R_z, R = rng.normal(size=n), rng.normal(size=3), np.diag([0.01, 0.02, 0.5]), yaw_rotation(0.3)
    _, P_new = slam3d.add_landmark(x, P, z, R_z, R)
    _, grad_x, grad_z = slam3d.initial_point(x, z, R)
    T = np.zeros((n + 3, n + 3))
    T[:n, :n] = np.eye(n)
    T[n:, :6] = grad_x
    T[n:, n:] = grad_z
    joint = np.block([[P, np.zeros((n, 3))], [np.zeros((3, n)), R_z]])
    np.testing.assert_allclose(P_new, T @ joint @ T.T, atol=1e-12)


def flight(seed: int, checkpoints_s: tuple[float, ...]) -> list[tuple[float, float]]:
    """One flight: (position NEES, vehicle NEES) at each checkpoint (module docstring)."""
    rng = np.random.default_rng(seed)
    dt, omega_var, reach = 0.5, 0.02, 30.0
    ground = rng.uniform(-80, 80, (150, 2))
    relief = 6.0 * np.sin(ground[:, 0] / 17.0) * np.cos(ground[:, 1] / 23.0) + rng.uniform(
        0, 12, 150
    )  # hills, buildings
    world = np.column_stack([ground, relief])
    p, v = np.array([0.0, 0.0, 20.0]), np.array([3.0, 0.5, 0.2])
    x = np.concatenate([p + rng.normal(0, 0.1, 3), v + rng.normal(0, 0.05, 3)])
    P = np.diag([0.01] * 3 + [0.0025] * 3)
    known: dict[int, int] = {}
    out, t, yaw = [], 0.0, 0.0
    for checkpoint in checkpoints_s:
        while t < checkpoint - 1e-9:
            step = rng.normal(0, np.sqrt(omega_var), 3)
            p, v = p + (v + step) * dt, v + step
            x, P = slam3d.predict(x, P, dt, omega_var)
            t += dt
            yaw = np.arctan2(v[1], v[0])
            R = yaw_rotation(yaw)  # the body's rotation, known (from VO in the paper)
            for i in np.flatnonzero(np.linalg.norm(world - p, axis=1) < reach):
                body = R.T @ (world[i] - p)
                along = body / np.linalg.norm(body)  # a triangulated point: long along its line of sight
                R_z = 0.05**2 * np.eye(3) + (0.02 * np.linalg.norm(body)) ** 2 * np.outer(along, along)
                z = body + rng.multivariate_normal(np.zeros(3), R_z)
                if i not in known:
                    known[i] = slam3d.landmarks(x)
                    x, P = slam3d.add_landmark(x, P, z, R_z, R)
                    continue
                h, H = slam3d.observe(x, known[i], R)
                x, P, _ = gated_update(x, P, z - h, H, R_z, np.inf)
        error = x[:6] - np.concatenate([p, v])
        out.append(
            (
                float(error[:3] @ np.linalg.solve(P[:3, :3], error[:3])),
                float(error @ np.linalg.solve(P[:6, :6], error)),
            )
        )
    return out


def test_the_3d_filter_is_consistent_over_30_flights():
    checkpoints = (20.0, 40.0, 60.0)
    nees = np.array([flight(seed, checkpoints) for seed in range(30)])  # (seeds, checkpoints, 2)
    for dof, column in ((3, 0), (6, 1)):
        low, high = chi2_band(dof, runs=30)
        means = nees[:, :, column].mean(axis=0)
        assert np.all((low <= means) & (means <= high)), (dof, means, (low, high))
