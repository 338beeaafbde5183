"""EKF-SLAM core (vision EKF-SLAM paper): Jacobians against finite differences, the map growth
against the paper's P <- Y P Y^T, the in-place update against the textbook one, and consistency
(pose and landmark NEES inside their 95% chi-square bands) over seeded Monte Carlo runs."""

import numpy as np
import pytest
from scipy.stats import chi2

from bus.angles import wrap_angle
from vehicle.models.landmarks import (
    add_landmark_with_errors,
    add_landmarks,
    landmark_from,
    observe,
    predict_pose,
    update,
)

pytestmark = pytest.mark.monte_carlo


def _numeric_jacobian(f, at: np.ndarray, *, bearing: bool = False, eps: float = 1e-6) -> np.ndarray:
    """Forward differences of f at ``at``; with ``bearing`` the second output is an angle (wrapped)."""
    base, columns = f(at), []
    for i in range(len(at)):
        step = np.zeros_like(at)
        step[i] = eps
        d = f(at + step) - base
        if bearing:
            d[1] = wrap_angle(d[1])
        columns.append(d / eps)
    return np.stack(columns, axis=1)


def _spd(rng, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n)) * 0.3
    return A @ A.T + 0.05 * np.eye(n)


def test_observation_jacobians_match_finite_differences():
    rng = np.random.default_rng(1)
    for _ in range(20):
        x = np.concatenate([[*rng.normal(size=2) * 5, rng.uniform(-3, 3)], rng.normal(size=6) * 20])
        j = int(rng.integers(0, 3))

        _, H_pose, H_landmark = observe(x, 3, j)
        numeric = _numeric_jacobian(lambda state: observe(state, 3, j)[0], x, bearing=True)
        np.testing.assert_allclose(H_pose, numeric[:, :3], atol=1e-5)
        np.testing.assert_allclose(H_landmark, numeric[:, 3 + 2 * j : 5 + 2 * j], atol=1e-5)
        others = np.delete(numeric, [0, 1, 2, 3 + 2 * j, 4 + 2 * j], axis=1)
        assert np.abs(others).max() < 1e-9  # nothing else enters the observation


def test_initialisation_jacobians_match_finite_differences():
    rng = np.random.default_rng(2)
    for _ in range(20):
        pose = np.array([*rng.normal(size=2) * 5, rng.uniform(-3, 3)])
        z = np.array([rng.uniform(1, 30), rng.uniform(-3, 3)])
        _, Gx, Gz = landmark_from(pose, z)
        np.testing.assert_allclose(Gx, _numeric_jacobian(lambda p: landmark_from(p, z)[0], pose), atol=1e-4)
        np.testing.assert_allclose(Gz, _numeric_jacobian(lambda q: landmark_from(pose, q)[0], z), atol=1e-4)


def test_a_batch_of_new_landmarks_grows_the_covariance_as_y_p_y_transposed():
    rng = np.random.default_rng(3)
    x, P = np.array([1.0, -2.0, 0.4, 0.01, 5.0, 6.0]), _spd(rng, 6)  # pose with a gyro bias + 1 landmark
    zs, R = np.array([[10.0, 0.3], [4.0, -1.2], [7.5, 2.9]]), np.diag([0.09, 0.0004])
    x_batch, P_batch = add_landmarks(x, P, zs, R)
    x_seq, P_seq = x, P  # the paper: one Y per landmark
    for z in zs:
        point, Gx, Gz = landmark_from(x, z)
        n = len(x_seq)
        Y = np.zeros((n + 2, n + 2))
        Y[:n, :n] = np.eye(n)
        Y[n:, :3], Y[n:, n:] = Gx, Gz
        big = np.zeros((n + 2, n + 2))
        big[:n, :n], big[n:, n:] = P_seq, R
        x_seq, P_seq = np.concatenate([x_seq, point]), Y @ big @ Y.T
    np.testing.assert_allclose(x_batch, x_seq)
    np.testing.assert_allclose(P_batch, P_seq, atol=1e-12)


@pytest.mark.parametrize("range_state, bearing_state", [(4, 5), (4, None), (None, 5)])
def test_a_landmark_with_error_states_grows_the_covariance_as_y_p_y_transposed(range_state, bearing_state):
    """Range read r (1 + s) + white, bearing beta + b + white: the landmark is g(pose, z_r / (1 + s),
    z_b - b), Y over [pose, s, b] from finite differences, the white noise through d g / d z."""
    rng = np.random.default_rng(5)
    x, P = np.array([1.0, -2.0, 0.4, 0.01, 0.03, -0.02, 5.0, 6.0]), _spd(rng, 8)  # pose, bias, s, b, 1 landmark
    z, R_white = np.array([4.0, 0.7]), np.diag([0.01, 0.0004])

    def g(state_and_z: np.ndarray) -> np.ndarray:
        state, (r, b) = state_and_z[:8], state_and_z[8:]
        s = state[range_state] if range_state is not None else 0.0
        offset = state[bearing_state] if bearing_state is not None else 0.0
        return landmark_from(state, np.array([r / (1.0 + s), b - offset]))[0]

    J = _numeric_jacobian(g, np.concatenate([x, z]))
    x_new, P_new = add_landmark_with_errors(x, P, z, R_white, range_state, bearing_state)
    np.testing.assert_allclose(x_new[-2:], g(np.concatenate([x, z])))
    Y = np.vstack([np.hstack([np.eye(8), np.zeros((8, 2))]), J])
    big = np.zeros((10, 10))
    big[:8, :8], big[8:, 8:] = P, R_white
    np.testing.assert_allclose(P_new, Y @ big @ Y.T, rtol=1e-5, atol=1e-6)  # forward differences


def test_the_in_place_update_equals_the_textbook_update():
    rng = np.random.default_rng(4)
    x = np.concatenate([[0.5, 0.2, 0.3], rng.normal(size=10) * 15])
    P = _spd(rng, 13)
    R = np.diag([0.09, 0.0004])
    predicted, H_pose, H_landmark = observe(x, 3, 2)
    H = np.zeros((2, 13))
    H[:, :3], H[:, 7:9] = H_pose, H_landmark
    z = predicted + np.array([0.2, 0.01])
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    x_ref = x + K @ np.array([z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
    P_ref = (np.eye(13) - K @ H) @ P @ (np.eye(13) - K @ H).T + K @ R @ K.T  # Joseph form
    memory = P.__array_interface__["data"][0]
    result = update(x, P, 3, 2, z, R, gate=1e9)
    assert result.accepted and P.__array_interface__["data"][0] == memory  # P updated where it is
    np.testing.assert_allclose(x, x_ref, atol=1e-12)
    np.testing.assert_allclose(P, P_ref, atol=1e-10)
    np.testing.assert_array_equal(P, P.T)  # exactly symmetric
    assert not update(x, P, 3, 2, z + np.array([50.0, 0.0]), R, gate=13.8).accepted


def _circle_run(seed: int, *, duration_s: float = 60.0, dt_s: float = 0.1, believed_noise: float = 1.0):
    """One seeded 60 s circle (radius 20 m, 2 m/s) over 60 random landmarks; odometry (speed, yaw
    rate) with noise drives the prediction; range-bearing to landmarks within 12 m (at most 5 per
    step, known identities). The truth moves on exact arcs at 100 Hz with its own input wobble (the
    filter assumes constant inputs per step and moves along the mid-step heading: the world is
    richer than the filter; a plain Euler step's bias alone made the map NEES 4.4 per dof). Returns per-step
    pose NEES, the final NEES of the whole map and its degrees of freedom (2 per landmark).
    ``believed_noise`` scales the sensor noise the filter assumes (1: the truth's)."""
    rng = np.random.default_rng(seed)
    speed, radius, sub = 2.0, 20.0, 10
    sigma_v, sigma_w, R = 0.05, 0.02, np.diag([0.1**2, 0.01**2])
    gate = chi2.ppf(0.9999, 2)
    landmarks = rng.uniform(-32, 32, size=(60, 2))
    truth = np.array([radius, 0.0, np.pi / 2])
    x, P = truth + rng.normal(size=3) * [0.1, 0.1, 0.01], np.diag([0.01, 0.01, 1e-4])
    mapped: dict[int, int] = {}
    pose_nees = []
    for _ in range(round(duration_s / dt_s)):
        w_true = speed / radius
        for _ in range(sub):  # truth: exact arcs, slightly wobbling inputs
            v, w = speed * (1 + 0.01 * rng.normal()), w_true * (1 + 0.01 * rng.normal())
            h = dt_s / sub
            truth = truth + [
                v / w * (np.sin(truth[2] + w * h) - np.sin(truth[2])),
                -v / w * (np.cos(truth[2] + w * h) - np.cos(truth[2])),
                w * h,
            ]
        v_m, w_m = speed + sigma_v * rng.normal(), w_true + sigma_w * rng.normal()
        mid = x[2] + 0.5 * w_m * dt_s  # the heading halfway through the step
        c, s = np.cos(mid), np.sin(mid)
        F = np.array([[1, 0, -v_m * dt_s * s], [0, 1, v_m * dt_s * c], [0, 0, 1]])
        G = np.array([[dt_s * c, -0.5 * v_m * dt_s**2 * s], [dt_s * s, 0.5 * v_m * dt_s**2 * c], [0, dt_s]])
        # process noise: the input noise, plus the input wobble and the 1% speed model error
        Q = G @ np.diag([sigma_v**2 + (0.01 * speed) ** 2, sigma_w**2 + (0.01 * w_true) ** 2]) @ G.T
        predict_pose(x, P, F, Q, x[:3] + [v_m * dt_s * c, v_m * dt_s * s, w_m * dt_s])
        d = landmarks - truth[:2]
        seen = np.flatnonzero(np.hypot(d[:, 0], d[:, 1]) < 12.0)[:5]
        new = []
        for i in seen:
            z = np.array([np.hypot(*d[i]), wrap_angle(np.arctan2(d[i, 1], d[i, 0]) - truth[2])])
            z = z + rng.normal(size=2) * np.sqrt(np.diag(R))
            if i in mapped:
                update(x, P, 3, mapped[i], z, R * believed_noise**2, gate=gate)
            else:
                new.append((i, z))
        if new:
            base = (len(x) - 3) // 2
            x, P = add_landmarks(x, P, np.array([z for _, z in new]), R * believed_noise**2)
            for k, (i, _) in enumerate(new):
                mapped[i] = base + k
        e = np.array([*(x[:2] - truth[:2]), wrap_angle(x[2] - truth[2])])
        pose_nees.append(float(e @ np.linalg.solve(P[:3, :3], e)))
    order = sorted(mapped, key=mapped.get)  # the map's slots in state order
    e_map = x[3:] - landmarks[order].ravel()
    map_nees = float(e_map @ np.linalg.solve(P[3:, 3:], e_map))
    return np.array(pose_nees), map_nees, 2 * len(order)


@pytest.mark.parametrize("runs", [50])
def test_pose_and_landmark_nees_are_inside_their_bands_over_monte_carlo_runs(runs):
    results = [_circle_run(seed) for seed in range(runs)]
    pose = np.mean([r[0] for r in results], axis=0)  # run-averaged NEES per step (3 dof)
    lo, hi = chi2.ppf([0.025, 0.975], 3 * runs) / runs
    inside = np.mean((pose >= lo) & (pose <= hi))
    assert inside >= 0.9, f"run-averaged pose NEES inside [{lo:.2f}, {hi:.2f}] for only {inside:.0%} of steps"
    # the map's landmarks share the pose error, so they are not independent samples: one joint map
    # NEES per run (chi2 with 2 m dof), summed over the independent runs
    total, dof = sum(r[1] for r in results), sum(r[2] for r in results)
    lo, hi = chi2.ppf([0.025, 0.975], dof)
    assert lo <= total <= hi, f"map NEES {total / dof:.2f} per dof outside [{lo / dof:.2f}, {hi / dof:.2f}]"


def test_the_check_fails_for_a_filter_that_believes_its_camera_too_much():
    """Control: the same runs with the sensor noise believed 3x smaller than it is."""
    results = [_circle_run(seed, believed_noise=1 / 3) for seed in range(20)]
    pose = np.mean([r[0] for r in results], axis=0)
    hi = chi2.ppf(0.975, 3 * 20) / 20
    assert np.mean(pose > hi) > 0.5
