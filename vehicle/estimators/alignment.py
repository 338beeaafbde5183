"""Initial pose without a launch-pad prior, as after a restart in flight (pure).

Position from the latest GNSS fix; heading from the GNSS track between two fixes at least
``baseline_s`` apart and ``min_chord_m`` apart. On an arc of constant turn rate the chord points
along the heading at mid-time, so the heading at the second fix is the chord direction plus half
the yaw turned in between (integrated from the gyro). Heading variance: the two fixes' noise across
the chord, 2 sigma^2 / d^2, doubled to cover turn-rate changes and gyro bias.
"""

from __future__ import annotations

import math

import numpy as np

from bus.angles import wrap_angle
from vehicle.estimators.shallow import shallow_copy


class GnssAlignment:
    def __init__(self, *, baseline_s: float = 2.0, min_chord_m: float = 6.0) -> None:
        self.baseline_us, self.min_chord_m = round(baseline_s * 1e6), min_chord_m
        self._first: tuple[int, np.ndarray, float] | None = None  # (stamp, fix, yaw turned so far)
        self._turned_rad = 0.0
        self._rate_stamp: tuple[int, float] | None = None

    def copy(self) -> GnssAlignment:
        """An independent copy: its fields are numbers and tuples, replaced, never changed in place."""
        return shallow_copy(self)

    def yaw_rate(self, stamp_us: int, rate_radps: float) -> None:
        """Integrate the measured yaw rate (rad/s) up to ``stamp_us``."""
        if self._rate_stamp is not None and stamp_us > self._rate_stamp[0]:
            self._turned_rad += self._rate_stamp[1] * (stamp_us - self._rate_stamp[0]) * 1e-6
        self._rate_stamp = (stamp_us, rate_radps)

    def fix(
        self, stamp_us: int, position_m: np.ndarray, covariance_m2: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """A fix (2,) with covariance (2, 2); returns pose [x, y, theta] (3,) and covariance (3, 3) once aligned."""
        if self._first is None:
            self._first = (stamp_us, position_m.copy(), self._turned_rad)
            return None
        t0, p0, turned0 = self._first
        chord = position_m - p0
        distance = float(np.hypot(*chord))
        if stamp_us - t0 < self.baseline_us or distance < self.min_chord_m:
            if stamp_us - t0 > 5 * self.baseline_us:  # standing still or too slow: start over
                self._first = (stamp_us, position_m.copy(), self._turned_rad)
            return None
        turned = self._turned_rad - turned0
        heading = wrap_angle(math.atan2(chord[1], chord[0]) + 0.5 * turned)
        sigma2 = float(np.trace(covariance_m2)) / 2.0
        cov = np.zeros((3, 3))
        cov[:2, :2] = covariance_m2
        cov[2, 2] = 2.0 * (2.0 * sigma2 / distance**2) + (0.1 * turned) ** 2
        return np.array([position_m[0], position_m[1], heading]), cov
