"""Staged validation, stage 1 (cooperative-localization paper): with perfect inputs and measurements
every vehicle filter reproduces the truth, on every trajectory kind (the filters still believe the
nominal datasheet; only the world is noise-free)."""

import pytest

from bus.config import SensorSpec
from experiments.harness import pose_nees_series

NOISE_FREE = SensorSpec(
    gyro_sigma_radps=0.0,
    gyro_bias_sigma_radps=0.0,
    gyro_bias_walk_radps_rtsec=0.0,
    accel_sigma_mps2=0.0,
    odom_speed_sigma_mps=0.0,
    odom_yaw_rate_sigma_radps=0.0,
    gnss_sigma_m=1e-9,
    prior_sigma_m=1e-9,
    prior_heading_sigma_rad=1e-12,
)


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
@pytest.mark.parametrize("trajectory", ["circle", "figure8", "waypoints"])
def test_a_noise_free_world_is_reproduced(kind, trajectory):
    _, errors = pose_nees_series(
        1, duration_s=20.0, trajectory=trajectory, world_sensors=NOISE_FREE, estimator_spec=SensorSpec(), kind=kind
    )
    assert len(errors) == 21 and errors.max() < 1e-6
