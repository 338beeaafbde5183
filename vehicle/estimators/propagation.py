"""What one prediction is driven by: the held inputs' means over the interval and their noise
(vehicle.estimators.inputs), chosen as every vehicle filter chooses them. Pure.

- the yaw rate: visual odometry's while it is recent (drift-free, it beats an integrated gyro whose
  bias nothing observes), else the gyro's while it is fresh, else the wheels' (their noise growing
  with the angle turned where the datasheet says so);
- the speed: the wheels' or visual odometry's, its noise growing with the distance travelled where
  the datasheet says so;
- an input held past its next sample's due time adds the walk of what it stands for (the vehicle's
  manoeuvres, ``sensors.speed_walk_mps_rtsec`` and ``sensors.yaw_rate_walk_radps_rtsec``).
"""

from __future__ import annotations

from dataclasses import dataclass

from bus.config import SensorSpec
from vehicle.estimators.inputs import swept
from vehicle.estimators.state import FilterState
from vehicle.models import unicycle
from vehicle.models.input_noise import InputNoise

GYRO_STALE_PERIODS = 5
VISUAL_STALE_US = 500_000  # visual odometry this old no longer gives the yaw rate (the gyro does)


@dataclass(frozen=True, slots=True)
class Interval:
    """The means of the inputs over one prediction interval of ``dt`` s and their noise."""

    speed_mps: float
    rate_radps: float
    dt: float
    noise: InputNoise


def close_inputs(s: FilterState, spec: SensorSpec, stamp_us: int, gyro_period_us: int) -> Interval:
    """Close the held inputs of ``s`` at ``stamp_us`` (> s.time_us): their means since s.time_us and
    the noise of those means (module docstring)."""
    dt = (stamp_us - s.time_us) * 1e-6
    # inputs held past their next sample's due time: what the vehicle's manoeuvres may have changed
    speed_walk = spec.speed_walk_mps_rtsec**2 * s.speed.walk_s(stamp_us)
    gyro_walk, odom_walk = s.gyro.walk_s(stamp_us), s.odom_yaw.walk_s(stamp_us)
    speed, speed_factor = s.speed.close(stamp_us)
    gyro, gyro_factor = s.gyro.close(stamp_us)
    odom_yaw, odom_factor = s.odom_yaw.close(stamp_us)
    visual = s.visual_us >= 0 and stamp_us - s.visual_us <= VISUAL_STALE_US
    fresh = (
        not visual and s.gyro.stamp_us is not None and stamp_us - s.gyro.stamp_us <= GYRO_STALE_PERIODS * gyro_period_us
    )
    if fresh:
        rate, rate_var, rate_source = gyro, spec.gyro_sigma_radps**2 * gyro_factor, s.gyro
    else:
        rate, rate_var, rate_source = odom_yaw, spec.odom_yaw_rate_sigma_radps**2 * odom_factor, s.odom_yaw
    rate_var += spec.yaw_rate_walk_radps_rtsec**2 * (gyro_walk if fresh else odom_walk)
    speed_var = spec.odom_speed_sigma_mps**2 * speed_factor + speed_walk
    if spec.odom_travel_sigma_m:  # along-track error growing with the distance travelled
        speed_var += spec.odom_travel_sigma_m**2 * swept(s.speed.segments) / (dt * dt)
    if spec.odom_turn_sigma_rad and not fresh:  # heading error growing with the angle turned
        rate_var += spec.odom_turn_sigma_rad**2 * swept(rate_source.segments) / (dt * dt)
    noise = InputNoise(
        speed_var=speed_var,
        yaw_rate_var=rate_var,
        bias_walk_var=spec.gyro_bias_walk_radps_rtsec**2,
        use_bias=fresh,
        steps=unicycle.pieces(s.speed.segments, rate_source.segments),
    )
    return Interval(speed, rate, dt, noise)
