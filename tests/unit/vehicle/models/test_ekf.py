"""EKF building blocks: Joseph update keeps P SPD, the gate rejects outliers, noise-free exactness."""

import numpy as np
import pytest

from bus import messages as m
from bus.config import SensorSpec
from bus.spd import spd4
from bus.statistics import gate_threshold
from experiments.harness import pose_nees_series
from vehicle.estimators import ekf
from vehicle.models import unicycle
from vehicle.models.kalman import gated_update


def test_gate_threshold_matches_chi_square_quantiles():
    assert gate_threshold(2, 0.95) == pytest.approx(5.991, abs=1e-3)
    assert gate_threshold(1, 0.99) == pytest.approx(6.635, abs=1e-3)


def test_joseph_update_keeps_covariance_symmetric_positive_definite():
    rng = np.random.default_rng(0)
    x, P = np.zeros(4), np.diag([4.0, 4.0, 0.1, 1e-4])
    for _ in range(200):
        x, P, result = gated_update(x, P, rng.normal(0, 1, 2), np.eye(2, 4), np.eye(2) * 1e-6, 1e9)
        assert result.accepted
    assert np.allclose(P, P.T) and np.all(np.linalg.eigvalsh(P) > 0)


def test_joseph_update_on_the_columns_a_sighting_touches_is_the_full_joseph_update():
    """A landmark sighting in a large map (H zero but on a few states), updated in O(n^2 m): the
    same state and covariance as the O(n^3) form, and still positive definite."""
    rng = np.random.default_rng(3)
    n, columns = 60, np.r_[0:3, 30:33]
    A = rng.normal(size=(n, n))
    P = A @ A.T / n + np.eye(n) * 1e-3
    H = np.zeros((3, n))
    H[:, columns] = rng.normal(size=(3, 6))
    y, R = rng.normal(size=3), np.diag([0.2, 0.3, 0.4])
    x_full, P_full, full = gated_update(np.zeros(n), P, y, H, R, 1e9)
    x_cols, P_cols, cols = gated_update(np.zeros(n), P, y, H, R, 1e9, columns=columns)
    assert cols.nis == pytest.approx(full.nis, rel=1e-10)
    np.testing.assert_allclose(x_cols, x_full, rtol=0, atol=1e-10)
    np.testing.assert_allclose(P_cols, P_full, rtol=0, atol=1e-10)
    assert np.array_equal(P_cols, P_cols.T) and np.linalg.eigvalsh(P_cols).min() > 0


def test_gate_rejects_an_outlier_and_leaves_the_state_untouched():
    x, P = np.zeros(4), np.eye(4)
    x2, P2, result = gated_update(x, P, np.array([100.0, 0.0]), np.eye(2, 4), np.eye(2), gate_threshold(2, 0.999))
    assert not result.accepted and result.test_ratio > 1
    assert x2 is x and P2 is P


def test_prediction_follows_the_exact_arc():
    x = np.array([0.0, -10.0, 0.0, 0.0])
    for _ in range(int(2 * np.pi * 10 / 2.0 / 0.01)):  # one lap of a 10 m circle at 2 m/s
        x = unicycle.propagate_mean(x, 2.0, 0.2, 0.01)
    np.testing.assert_allclose(x[:2], [0.0, -10.0], atol=0.05)


def test_noise_free_sensors_give_exact_tracking():
    """Staged validation, step one (cooperative-localization paper): no noise, no error."""
    tiny = SensorSpec(
        gyro_sigma_radps=1e-9,
        gyro_bias_sigma_radps=1e-9,
        gyro_bias_walk_radps_rtsec=0.0,
        accel_sigma_mps2=0.0,
        odom_speed_sigma_mps=1e-9,
        odom_yaw_rate_sigma_radps=1e-9,
        gnss_sigma_m=1e-6,
        prior_sigma_m=1e-9,
        prior_heading_sigma_rad=1e-9,
    )
    _, errors = pose_nees_series(3, duration_s=20.0, trajectory="waypoints", estimator_spec=tiny, world_sensors=tiny)
    assert errors.max() < 1e-4


def test_the_float_prediction_equals_the_matrix_one():
    rng = np.random.default_rng(4)
    for _ in range(300):
        A = rng.normal(size=(4, 4))
        P, x = A @ A.T + 0.1 * np.eye(4), rng.normal(size=4)
        v, w = rng.uniform(0, 10), rng.normal()
        steps = [(0.01, v, w), (0.01, v + rng.normal(0, 0.1), w + rng.normal(0, 0.1))]
        for use_bias in (True, False):
            kw = dict(
                speed_var=rng.uniform(0, 1e-2),
                yaw_rate_var=rng.uniform(0, 1e-2),
                bias_walk_var=1e-7,
                use_bias=use_bias,
                steps=steps,
            )
            slow, fast = unicycle.predict(x, P, v, w, 0.02, **kw), unicycle.predict_fast(x, P, v, w, 0.02, **kw)
            np.testing.assert_allclose(fast[0], slow[0], atol=1e-12)
            np.testing.assert_allclose(fast[1], slow[1], rtol=1e-11, atol=1e-14)


def test_the_positive_definiteness_check_agrees_with_cholesky():
    rng = np.random.default_rng(5)
    for _ in range(500):
        A = rng.normal(size=(4, 4))
        P = A @ A.T + rng.normal(0, 1.0) * np.eye(4)  # sometimes indefinite
        try:
            np.linalg.cholesky(P)
            expected = True
        except np.linalg.LinAlgError:
            expected = False
        assert spd4(P) is expected
    for bad in (np.nan, np.inf, -np.inf):
        P = np.eye(4)
        P[1, 2] = P[2, 1] = bad
        assert not spd4(P)


def _after_odometry(spec: SensorSpec, speed_mps: float, yaw_rate_radps: float, seconds: float) -> np.ndarray:
    """The covariance (4, 4) of the default EKF after ``seconds`` of constant odometry from a pose at 0."""
    f = ekf.build(vehicle_id=1, spec=spec, gate_probability=0.999)
    f.handle(m.PosePrior(1, 0, 0, np.zeros(3), np.diag([1e-4, 1e-4, 1e-4])))
    period = round(1e6 / spec.odom_rate_hz)
    for k in range(round(seconds * 1e6 / period) + 1):
        f.handle(m.WheelOdometry(1, k * period, k, speed_mps, yaw_rate_radps))
        f.cycle(k * period)
    return f.P


def test_odometry_error_grows_with_the_turns_and_the_distance_when_the_datasheet_says_so():
    plain = SensorSpec(odom_speed_sigma_mps=0.01, odom_yaw_rate_sigma_radps=0.01)
    turning = plain.model_copy(update={"odom_turn_sigma_rad": 0.1, "odom_travel_sigma_m": 0.05})
    # a turn on the spot of 1 rad: heading variance grows by 0.1^2 per radian turned
    grown = _after_odometry(turning, 0.0, 0.5, 2.0)[2, 2] - _after_odometry(plain, 0.0, 0.5, 2.0)[2, 2]
    assert grown == pytest.approx(0.1**2 * 1.0, rel=0.02)
    # 1 m straight ahead (along x): along-track variance grows by 0.05^2 per metre; no turn, no heading growth
    straight, base = _after_odometry(turning, 0.5, 0.0, 2.0), _after_odometry(plain, 0.5, 0.0, 2.0)
    assert straight[0, 0] - base[0, 0] == pytest.approx(0.05**2 * 1.0, rel=0.02)
    assert straight[2, 2] == pytest.approx(base[2, 2])
