"""The unscented transform and the ``ukf`` estimator: exact on linear models, angle-aware across
+-pi, and its cooperative (CI) update agrees with the EKF's where the model is nearly linear."""

import numpy as np

from bus import messages as m
from bus.config import build_config
from vehicle.estimators import get_estimator
from vehicle.models import unscented as ut
from vehicle.models.cooperative import cooperative_update
from vehicle.models.cooperative_fixes import CooperativeFix

RNG = np.random.default_rng(3)
A = RNG.normal(size=(4, 4)) * 0.3
P0 = A @ A.T + np.eye(4) * 0.01


def test_a_linear_motion_is_transformed_exactly():
    F = np.eye(4) + RNG.normal(size=(4, 4)) * 0.1
    Q = np.diag([0.1, 0.2, 0.01, 1e-6])
    x = np.array([1.0, -2.0, 0.3, 0.01])
    mean, P = ut.propagate(x, P0, lambda p: F @ p, Q)
    assert np.allclose(mean, F @ x, atol=1e-12) and np.allclose(P, F @ P0 @ F.T + Q, atol=1e-12)


def test_the_heading_mean_and_residuals_are_circular():
    x = np.array([0.0, 0.0, np.pi - 0.01, 0.0])
    P = np.diag([1.0, 1.0, 0.04, 1e-6])
    mean, P_new = ut.propagate(x, P, lambda p: p, np.zeros((4, 4)))
    assert abs(abs(mean[2]) - (np.pi - 0.01)) < 1e-9 and np.isclose(P_new[2, 2], 0.04)


def test_a_linear_measurement_gives_the_kalman_terms():
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    x = np.array([3.0, 4.0, 0.2, 0.0])
    z_hat, P_zz, P_xz = ut.measure(x, P0, lambda p: H @ p, angle_rows=())
    assert np.allclose(z_hat, H @ x) and np.allclose(P_zz, H @ P0 @ H.T) and np.allclose(P_xz, P0 @ H.T)


def test_the_ukf_ci_update_agrees_with_the_ekf_one_when_the_neighbour_is_far():
    """At 200 m with metre-level uncertainty the range-bearing model is nearly linear: same fusion."""
    config = build_config({"vehicle": {"estimator": "ukf"}})
    ukf = get_estimator(config.for_vehicle(), 1)
    P = np.diag([1.0, 1.0, 1e-4, 1e-6])
    x = np.array([0.0, 0.0, 0.1, 0.0])
    ukf.handle(m.PosePrior(1, 0, 0, x[:3], P[:3, :3]))
    ukf.state.P[3, 3] = P[3, 3]
    fix = CooperativeFix(1, 0, 0, 2, 200.5, 0.89, np.diag([0.09, 4e-4]), np.array([120.0, 160.0]), np.eye(2) * 0.5)
    ukf.handle(fix)
    x_ukf, P_ukf, result = cooperative_update(x, P, fix, ukf.gate, unscented=True)
    x_ekf, P_ekf, ekf_result = cooperative_update(x, P, fix, ukf.gate)
    assert ukf.counters.v2v_fused == 1 and np.array_equal(ukf.x, x_ukf) and np.array_equal(ukf.P, P_ukf)
    assert result.accepted and ekf_result.accepted and np.isclose(result.nis, ekf_result.nis, rtol=1e-3)
    assert np.allclose(ukf.x, x_ekf, atol=1e-3) and np.allclose(ukf.P, P_ekf, rtol=1e-2, atol=1e-8)
