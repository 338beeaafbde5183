"""What a vehicle's estimator says about itself, in its own frame and units, before any wire format:
the pose with its covariance and the inputs it moves with (``PoseEstimate``), and its health
(``Health``). ``bus.odometry_content`` and ``bus.mavlink_codec`` map them to MAVLink ODOMETRY and
ESTIMATOR_STATUS and back (the filter does not know MAVLink's NED 6 x 6 layout)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Altitude:
    """A vehicle's estimated height above its launch point (m, up: the origin of the altitude of
    ODOMETRY's local NED frame), its variance (m^2) and its covariance (m^2) with x and y."""

    height_m: float
    var: float
    cov_xy: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class PoseEstimate:
    """A planar pose estimate at ``stamp_us``: ``pose`` [x m, y m, yaw rad] (3,) with covariance
    ``pose_cov`` (3, 3), the forward speed (m/s) and yaw rate (rad/s) the vehicle moves with and
    their variances ((m/s)^2, (rad/s)^2); ``altitude`` where the estimator estimates its height (a
    UAV over relief), else None (the vehicle flies level at the configured altitude)."""

    vehicle_id: int
    stamp_us: int
    pose: np.ndarray
    pose_cov: np.ndarray
    speed_mps: float = 0.0
    speed_var: float = 0.0
    yaw_rate_radps: float = 0.0
    yaw_rate_var: float = 0.0
    altitude: Altitude | None = None


@dataclass(frozen=True)
class Health:
    """An estimator's health at ``stamp_us``: whether it trusts its GNSS receiver, the larger of the
    GNSS innovation test ratios (NIS / gate, > 1 rejects: PX4's convention) and the 1-sigma
    horizontal position accuracy (m)."""

    vehicle_id: int
    stamp_us: int
    gnss_healthy: bool
    gnss_test_ratio: float
    horizontal_sigma_m: float
