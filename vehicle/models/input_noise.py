"""The noise of one propagation's mean inputs (what ``vehicle.models.unicycle``'s motion model takes
by keyword), typed: the variances of the interval's mean speed and yaw rate, the gyro bias's random
walk, whether the rate is the gyro's (its bias then enters), and the inputs' hold pieces. Pure."""

from __future__ import annotations

from dataclasses import dataclass, replace


@dataclass(frozen=True, slots=True)
class InputNoise:
    speed_var: float  # (m/s)^2, of the interval's mean speed
    yaw_rate_var: float  # (rad/s)^2, of its mean yaw rate
    bias_walk_var: float  # rad^2/s^3, the gyro bias's random walk
    use_bias: bool = True  # the rate is the gyro's: its bias state enters
    steps: list[tuple[float, float, float]] | None = None  # the hold pieces (dt s, speed, rate)

    def kwargs(self) -> dict:
        """The motion model's keyword arguments (``unicycle.motion_model``)."""
        return {
            "speed_var": self.speed_var,
            "yaw_rate_var": self.yaw_rate_var,
            "bias_walk_var": self.bias_walk_var,
            "use_bias": self.use_bias,
            "steps": self.steps,
        }

    def with_steps(self, steps: list[tuple[float, float, float]] | None) -> InputNoise:
        return replace(self, steps=steps)
