"""Seeded sensor models: IMU with gyro bias random walk, wheel odometry, GNSS, launch-pad prior.

Each function is pure given its ``np.random.Generator``; no wall-clock anywhere.
"""

from __future__ import annotations

import numpy as np

from bus.config import SensorSpec

GRAVITY_MPS2 = 9.80665


def initial_gyro_bias(spec: SensorSpec, rng: np.random.Generator) -> np.ndarray:
    """A turn-on gyro bias (3,) in rad/s."""
    return rng.normal(0.0, spec.gyro_bias_sigma_radps, 3)


def walk_gyro_bias(bias: np.ndarray, spec: SensorSpec, dt_s: float, rng: np.random.Generator) -> np.ndarray:
    """One random-walk step of the gyro bias (3,) over ``dt_s``."""
    return bias + rng.normal(0.0, spec.gyro_bias_walk_radps_rtsec * np.sqrt(dt_s), 3)


def imu_sample(speed_mps: float, accel_fwd_mps2: float, yaw_rate_radps: float, bias: np.ndarray,
               spec: SensorSpec, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame (FRD) gyro (3,) rad/s and specific force (3,) m/s^2 of a level unicycle."""
    gyro = np.array([0.0, 0.0, yaw_rate_radps]) + bias + rng.normal(0.0, spec.gyro_sigma_radps, 3)
    specific_force = np.array([accel_fwd_mps2, speed_mps * yaw_rate_radps, -GRAVITY_MPS2])
    return gyro, specific_force + rng.normal(0.0, spec.accel_sigma_mps2, 3)


def odometry_sample(speed_mps: float, yaw_rate_radps: float, spec: SensorSpec,
                    rng: np.random.Generator) -> tuple[float, float]:
    """Measured (speed m/s, yaw rate rad/s)."""
    return (speed_mps + rng.normal(0.0, spec.odom_speed_sigma_mps),
            yaw_rate_radps + rng.normal(0.0, spec.odom_yaw_rate_sigma_radps))


def gnss_fix(position_m: np.ndarray, spec: SensorSpec, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal fix (2,) m and its reported covariance (2, 2) m^2."""
    return position_m + rng.normal(0.0, spec.gnss_sigma_m, 2), np.eye(2) * spec.gnss_sigma_m**2


def pose_prior(pose: np.ndarray, spec: SensorSpec, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Surveyed start pose (3,) and covariance (3, 3): what a vehicle knows before it moves."""
    sigmas = np.array([spec.prior_sigma_m, spec.prior_sigma_m, spec.prior_heading_sigma_rad])
    return pose + rng.normal(0.0, sigmas), np.diag(sigmas**2)


def range_bearing(pose: np.ndarray, target_xy_m: np.ndarray, spec: SensorSpec,
                  rng: np.random.Generator) -> tuple[float, float, np.ndarray]:
    """Range (m) and bearing (rad from the heading) of a target (2,) seen from ``pose`` (3,), with
    noise, and their covariance (2, 2)."""
    d = target_xy_m - pose[:2]
    noise = rng.normal(0.0, [spec.range_sigma_m, spec.bearing_sigma_rad])
    bearing = np.arctan2(d[1], d[0]) - pose[2] + noise[1]
    return (float(np.hypot(d[0], d[1]) + noise[0]), float((bearing + np.pi) % (2 * np.pi) - np.pi),
            np.diag([spec.range_sigma_m**2, spec.bearing_sigma_rad**2]))
