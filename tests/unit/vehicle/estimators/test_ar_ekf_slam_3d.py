"""``ar-ekf-slam-3d`` (vehicle.estimators.ar_ekf_slam_3d) and what it adds to the 3-D back end: a
landmark entered while a frame's shared errors are states keeps them as correlations (the paper's
P_new, widened); the velocity turns with the heading and its covariance with it; a vehicle whose GNSS
fixes keep failing the gate drops its map and takes its position from GNSS; and
a UAV flown over the relief with its GNSS jammed keeps its place on the map it builds."""

from __future__ import annotations

import numpy as np
import pytest

from bus import messages as m
from bus.config import ArSlamConfig, SensorSpec, build_config
from bus.sensors.camera3d import Camera3dSpec
from experiments.uav3d_flights import fly_in_process
from vehicle.estimators.ar_ekf_slam_3d import LOST_AFTER_FIXES, ArEkfSlam3d
from vehicle.estimators.ar_slam3d import ArSlam3d, _insert_point
from vehicle.models import slam3d


def _spd(n: int, rng: np.random.Generator) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


def test_a_landmark_entered_with_shared_errors_is_their_linear_function():
    """X = p + R z - R G c + R v: the joint covariance of the grown state is T blockdiag(P, R_z) T^T,
    the new rows inserted before the shared errors'."""
    rng = np.random.default_rng(0)
    head, shared = slam3d.HEAD + slam3d.POINT, 5  # the vehicle and one landmark, then the shared errors
    n = head + shared
    x, P = rng.normal(size=n), _spd(n, rng)
    z, R_z = rng.normal(size=3) * 10, _spd(3, rng) * 0.01
    rotation = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    G = rng.normal(size=(3, shared))
    x_new, P_new = _insert_point(x, P, head, z, R_z, -rotation @ G, rotation)
    T = np.zeros((n + 3, n + 3))
    T[:n, :n] = np.eye(n)
    T[n:, :3] = np.eye(3)
    T[n:, head:n] = -rotation @ G
    T[n:, n:] = rotation
    joint = T @ np.block([[P, np.zeros((n, 3))], [np.zeros((3, n)), R_z]]) @ T.T
    order = np.r_[:head, n : n + 3, head:n]  # the new landmark before the shared errors
    np.testing.assert_allclose(P_new, joint[np.ix_(order, order)], atol=1e-10)
    np.testing.assert_allclose(x_new[head : head + 3], x[:3] + rotation @ z)
    np.testing.assert_array_equal(x_new[head + 3 :], x[head:])


def test_the_velocity_turns_with_the_heading_and_its_covariance_with_it():
    x0 = np.array([0.0, 0.0, 15.0, 4.0, 0.0, 0.1])
    P0 = np.diag([1.0, 1.0, 1.0, 0.04, 0.01, 0.01])
    slam = ArSlam3d(x0, P0, spec=ArSlamConfig())
    slam.turn_velocity(np.pi / 2, 1e-4)
    np.testing.assert_allclose(slam.x[3:6], [0.0, 4.0, 0.1], atol=1e-12)
    np.testing.assert_allclose(np.diag(slam.P)[3:5], [0.01 + 1e-4 * 16.0, 0.04], atol=1e-12)
    assert np.all(np.linalg.eigvalsh(slam.P) > 0)


def _fix(t_s: float, xy) -> m.GnssFix:
    return m.GnssFix(1, round(t_s * 1e6), 0, np.array(xy, float), np.eye(2))


def test_a_vehicle_whose_fixes_keep_failing_the_gate_takes_its_position_from_gnss():
    estimator = ArEkfSlam3d(1, Camera3dSpec(rate_hz=10), ArSlamConfig())
    estimator.handle(m.PosePrior(1, 0, 0, np.zeros(3), np.diag([0.01, 0.01, 0.001])))
    for k in range(1, LOST_AFTER_FIXES + 1):  # 300 m off: every fix fails the gate
        estimator.handle(_fix(0.1 * k, [300.0, 0.0]))
    assert estimator.counters.gnss_rejected == LOST_AFTER_FIXES and estimator.resets == 1
    assert "lost track" in estimator.notices.take()[0].text
    assert np.linalg.norm(estimator.estimate(300_000).pose[:2] - [300.0, 0.0]) < 1e-9
    estimator.handle(_fix(0.1 * LOST_AFTER_FIXES + 0.1, [300.5, 0.0]))
    assert estimator.counters.gnss_accepted == 1


@pytest.fixture(scope="module")
def jammed_flight():
    config = build_config(
        {
            "world": {"vehicles": 1, "seed": 2},
            "clock": {"duration_s": 36},
            "vehicle": {"estimator": "ar-ekf-slam-3d"},
            "sensors": {"camera3d": {"rate_hz": 10}},
            "faults": [
                {"name": "j", "kind": "jam-gnss", "center_m": [0, 0], "radius_m": 500.0, "start_s": 8, "for_s": 22}
            ],
        }
    )
    return fly_in_process(config)[1]


def test_a_uav_keeps_its_place_on_its_map_through_a_jam(jammed_flight):
    jammed = jammed_flight.error_m[(jammed_flight.t_s >= 8) & (jammed_flight.t_s <= 30)]
    assert jammed_flight.fused > 500 and jammed_flight.resets == 0
    assert jammed.max() < 3.0, jammed.max()
    assert jammed_flight.error_m[jammed_flight.t_s >= 33].max() < 1.0


def test_between_frames_the_gyro_turns_the_heading_and_the_velocity():
    estimator = ArEkfSlam3d(1, Camera3dSpec(rate_hz=10), ArSlamConfig(), imu=SensorSpec())
    estimator.handle(m.PosePrior(1, 0, 0, np.zeros(3), np.diag([0.01, 0.01, 1e-4])))
    estimator.state.slam.x[3:5] = [4.0, 0.0]
    for k in range(101):  # 1 s of a 0.5 rad/s turn at 100 Hz
        estimator.handle(m.ImuSample(1, 10_000 * k, k, np.array([0.0, 0.0, 0.5]), np.zeros(3)))
    estimator.cycle(1_000_000)
    published = estimator.estimate(1_000_000)
    assert published.pose[2] == pytest.approx(0.5)
    spec = SensorSpec()
    assert published.pose_cov[2, 2] == pytest.approx(
        1e-4 + spec.gyro_bias_sigma_radps**2 + 100 * (0.01 * spec.gyro_sigma_radps) ** 2
    )
    np.testing.assert_allclose(estimator.state.slam.x[3:5], 4.0 * np.array([np.cos(0.5), np.sin(0.5)]), atol=1e-9)
