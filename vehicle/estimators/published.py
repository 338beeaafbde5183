"""What a vehicle filter's state says to the outside, as plain records (bus.estimate): the pose
estimate it publishes and its GNSS health. The wire format is not the filter's. Pure."""

from __future__ import annotations

import numpy as np

from bus.config import SensorSpec
from bus.estimate import Health, PoseEstimate
from bus.statistics import published_pose_cov
from vehicle.estimators.state import FilterState


def pose_estimate(s: FilterState, spec: SensorSpec, vehicle_id: int, t_us: int) -> PoseEstimate:
    """The pose at the last cycle (``t_us``), the wheel speed and the bias-corrected gyro rate."""
    gyro = s.gyro.value if s.gyro.value is not None else 0.0
    return PoseEstimate(
        vehicle_id=vehicle_id,
        stamp_us=max(t_us, s.time_us),
        pose=s.x[:3].copy(),
        pose_cov=published_pose_cov(s.P[:3, :3].copy(), spec.unmodelled_sigma_m),
        speed_mps=s.speed.value or 0.0,
        speed_var=spec.odom_speed_sigma_mps**2,
        yaw_rate_radps=gyro - float(s.x[3]),
        yaw_rate_var=spec.gyro_sigma_radps**2 + s.P[3, 3],
    )


def health(s: FilterState, spec: SensorSpec, vehicle_id: int, t_us: int) -> Health:
    """GNSS trusted or not, the larger GNSS test ratio, the 1-sigma horizontal accuracy."""
    h, P = s.gnss_health, s.P
    P = P if P is not None else np.eye(4) * 1e6
    ratio = max(h.last_test_ratio, h.last_mean_test_ratio)
    floor = spec.unmodelled_sigma_m**2
    return Health(vehicle_id, t_us, h.healthy, ratio, float(np.sqrt(0.5 * (P[0, 0] + P[1, 1]) + floor)))
