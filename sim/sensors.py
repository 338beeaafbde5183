"""Seeded sensor models: IMU with gyro bias random walk, wheel odometry, GNSS, launch-pad prior,
radio ranging.

Each function is pure given its noise (drawn by the caller from the vehicle's own
``np.random.Generator``) or its generator; no wall-clock anywhere.
"""

from __future__ import annotations

import numpy as np

from bus.config import SensorSpec

GRAVITY_MPS2 = 9.80665


def initial_gyro_bias(spec: SensorSpec, rng: np.random.Generator) -> np.ndarray:
    """A turn-on gyro bias (3,) in rad/s."""
    return rng.normal(0.0, spec.gyro_bias_sigma_radps, 3)


def imu_rows(
    speed_mps: np.ndarray,
    accel_fwd_mps2: np.ndarray,
    yaw_rate_radps: np.ndarray,
    bias: np.ndarray,
    gyro_noise: np.ndarray,
    accel_noise: np.ndarray,
) -> np.ndarray:
    """Body-frame (FRD) [gyro (3) rad/s, specific force (3) m/s^2] rows (N, 6) of N level unicycles
    at one step, given their speeds, forward accelerations and yaw rates (N,), gyro biases (N, 3)
    and this step's white noise (N, 3) each."""
    rows = np.empty((len(speed_mps), 6))
    rows[:, 0] = (0.0 + bias[:, 0]) + gyro_noise[:, 0]
    rows[:, 1] = (0.0 + bias[:, 1]) + gyro_noise[:, 1]
    rows[:, 2] = (yaw_rate_radps + bias[:, 2]) + gyro_noise[:, 2]
    rows[:, 3] = accel_fwd_mps2 + accel_noise[:, 0]
    rows[:, 4] = speed_mps * yaw_rate_radps + accel_noise[:, 1]
    rows[:, 5] = -GRAVITY_MPS2 + accel_noise[:, 2]
    return rows


def pose_prior(pose: np.ndarray, spec: SensorSpec, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Surveyed start pose (3,) and covariance (3, 3): what a vehicle knows before it moves."""
    sigmas = np.array([spec.prior_sigma_m, spec.prior_sigma_m, spec.prior_heading_sigma_rad])
    return pose + rng.normal(0.0, sigmas), np.diag(sigmas**2)


def range_bearing(pose: np.ndarray, target_xy_m: np.ndarray, noise: np.ndarray) -> tuple[float, float]:
    """Range (m, >= 0) and bearing (rad from the heading, wrapped) of a target (2,) seen from
    ``pose`` (3,), with this measurement's noise (2,) [range m, bearing rad] added."""
    d = target_xy_m - pose[:2]
    bearing = np.arctan2(d[1], d[0]) - pose[2] + noise[1]
    return abs(float(np.hypot(d[0], d[1]) + noise[0])), float((bearing + np.pi) % (2 * np.pi) - np.pi)
