"""Wheel slip seen as a jump in the wheel speed that the accelerometer did not feel (pure).

The guard keeps the speed level the wheels have been reading, moved on between readings by what the
forward accelerometer felt (the sum of its samples times the IMU period) and low-passed over the
readings. A reading further than ``threshold_mps`` from that level is a candidate jump; it counts
when the next reading stays near the new level (a one-sample spike, common with heavy-tailed noise,
is no slip, and that reading is taken at the level instead). A jump that counts is slip starting or
ending: it becomes an offset taken off every reading until the opposite jump takes it away, or until
``max_slip_s`` has passed (then the wheels are trusted again). Ground robots compare wheels with the
IMU the same way (wheel-inertial slip detection). The threshold is six sigma of the datasheet's
speed noise; two such spikes in a row, which a false slip needs, are a few in 10^8 readings even
with Student-t(5) noise. Without accelerometer samples since the last reading nothing is judged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from vehicle.estimators.shallow import shallow_copy

THRESHOLD_SIGMAS = 6.0
LEVEL_GAIN = 0.3  # low-pass of the level over readings
MAX_SLIP_S = 5.0


@dataclass
class SlipGuard:
    """Offsets wheel speed readings by the slip the accelerometer contradicts (module docstring).
    ``threshold_mps``: jump left unexplained that counts as slip; ``imu_period_s``: accelerometer period."""

    threshold_mps: float
    imu_period_s: float
    max_slip_s: float = MAX_SLIP_S
    offset_mps: float = 0.0
    slips: int = 0  # onsets seen
    _since_us: int = 0
    _level: float | None = None  # the slip-free speed the wheels have been reading (m/s)
    _felt_mps: float = 0.0  # speed change the accelerometer felt since the last reading
    _felt_samples: int = 0
    _pending: float | None = None  # a jump seen on the last reading, not confirmed yet

    @classmethod
    def for_datasheet(cls, odom_speed_sigma_mps: float, imu_rate_hz: float) -> SlipGuard:
        return cls(THRESHOLD_SIGMAS * max(odom_speed_sigma_mps, 1e-3), 1.0 / imu_rate_hz)

    def accelerometer(self, forward_mps2: float) -> None:
        """One accelerometer sample's forward specific force (m/s^2)."""
        if math.isfinite(forward_mps2):
            self._felt_mps += forward_mps2 * self.imu_period_s
            self._felt_samples += 1

    def correct(self, stamp_us: int, reading_mps: float) -> float:
        """The wheel speed reading (m/s) at ``stamp_us`` without the slip offset."""
        judged = self._level is not None and self._felt_samples > 0
        predicted = self._level + self._felt_mps if judged else reading_mps - self.offset_mps
        self._felt_mps, self._felt_samples = 0.0, 0
        residual = reading_mps - self.offset_mps - predicted
        if self._pending is not None and abs(residual - self._pending) < 0.5 * abs(self._pending):  # it held
            self.slips += int(self.offset_mps == 0.0)
            self.offset_mps += 0.5 * (self._pending + residual)
            self._since_us = stamp_us
            residual = reading_mps - self.offset_mps - predicted
        elif judged and self._pending is None and abs(residual) > self.threshold_mps:
            self._pending, self._level = residual, predicted
            return predicted
        self._pending = None
        if self.offset_mps and (
            abs(self.offset_mps) <= self.threshold_mps or stamp_us - self._since_us > self.max_slip_s * 1e6
        ):
            self.offset_mps = 0.0
            predicted, residual = reading_mps, 0.0  # wheels trusted again: the level follows them
        self._level = predicted + LEVEL_GAIN * residual
        return reading_mps - self.offset_mps

    def copy(self) -> SlipGuard:
        return shallow_copy(self)  # every field is an immutable scalar
