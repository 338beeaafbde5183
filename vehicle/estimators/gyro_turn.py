"""A 3-D camera vehicle's turn between camera frames (``ar-ekf-slam-3d``): each gyro sample turns the
published heading and adds to the turn the velocity has yet to take; the heading's variance grows by
the gyro's white noise and by its unknown bias over the time since the last frame (the datasheet's
``gyro_sigma_radps`` and ``gyro_bias_sigma_radps``: a bias is the same over that time, so its
variance grows with the square of it). Pure."""

from __future__ import annotations

from dataclasses import dataclass

from bus.angles import wrap_angle
from bus.config import SensorSpec


@dataclass
class Gyro:
    """What the gyro has said since the last frame: its last stamp (-1: none yet), the seconds since
    the frame, and the turn (rad) and its variance (rad^2) not yet applied to the velocity."""

    last_us: int = -1
    since_frame_s: float = 0.0
    turn_rad: float = 0.0
    turn_var: float = 0.0

    def sample(
        self, stamp_us: int, rate_radps: float, heading_rad: float, heading_var: float, imu: SensorSpec
    ) -> tuple[float, float]:
        """The heading (rad) and its variance (rad^2) after the sample of yaw rate ``rate_radps`` at
        ``stamp_us``, over the interval since the last (the same for a sample not after the last)."""
        if stamp_us <= self.last_us:
            return heading_rad, heading_var
        dt = (stamp_us - self.last_us) * 1e-6 if self.last_us >= 0 else 0.0
        self.last_us = stamp_us
        noise_var = (imu.gyro_sigma_radps * dt) ** 2
        bias_var = imu.gyro_bias_sigma_radps**2
        heading_rad = float(wrap_angle(heading_rad + rate_radps * dt))
        heading_var += noise_var + bias_var * ((self.since_frame_s + dt) ** 2 - self.since_frame_s**2)
        self.since_frame_s += dt
        self.turn_rad += rate_radps * dt
        self.turn_var += noise_var + bias_var * dt**2
        return heading_rad, heading_var

    def take_turn(self) -> tuple[float, float]:
        """The turn (rad) and its variance (rad^2) pending for the velocity, now taken (zeroed)."""
        turn = self.turn_rad, self.turn_var
        self.turn_rad = self.turn_var = 0.0
        return turn
