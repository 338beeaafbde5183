"""The world's high-rate sensors, every vehicle at once: the IMU at every step and the wheel
odometry at its period (sim.sensors.imu_rows, sim.true_errors.odometry_rows), from the same draws,
in the same order and with the same arithmetic as one vehicle at a time would (pure given the draws).

Per step, a few array operations for the whole swarm instead of a few dozen Python calls per
vehicle; each vehicle's rows are cut from the step rows at the end of an advance (``StepRows``). The
IMU rows of an advance are worked out at its end, every step at once, from what each step kept
(``ImuSteps``: the same element-wise arithmetic on the same values).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from bus.config import SensorTruth
from bus.topics import Topic
from sim import sensors
from sim.true_errors import OdometryDraws, odometry_rows

Silenced = Callable[[str, int], "np.ndarray | None"]  # (topic, t_us) -> (N,) bool, None for none


class StepRows:
    """One topic's rows over an advance: per step its stamp, every vehicle's row (N, w) and which
    vehicles were silenced (N,) bool, or None for none."""

    def __init__(self) -> None:
        self._stamps: list[int] = []
        self._rows: list[np.ndarray] = []
        self._silenced: list[np.ndarray | None] = []

    def add(self, stamp_us: int, rows: np.ndarray, silenced: np.ndarray | None = None) -> None:
        self._stamps.append(stamp_us)
        self._rows.append(rows)
        self._silenced.append(silenced)

    def per_vehicle(self, vehicles: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """For each of the ``vehicles``: the stamps (k,) us and rows (k, w) it was not silenced at."""
        if not self._stamps:
            return [(np.zeros(0, np.int64), np.zeros((0, 0)))] * vehicles
        stamps, rows = np.array(self._stamps, dtype=np.int64), self._stacked()  # (S,), (S, N, w)
        if all(s is None for s in self._silenced):
            return [(stamps, np.ascontiguousarray(rows[:, n])) for n in range(vehicles)]
        heard = ~np.array([np.zeros(vehicles, bool) if s is None else s for s in self._silenced])  # (S, N)
        return [(stamps[heard[:, n]], rows[heard[:, n], n]) for n in range(vehicles)]

    def _stacked(self) -> np.ndarray:
        """Every step's rows (S, N, w)."""
        return np.stack(self._rows)


class ImuSteps(StepRows):
    """The IMU's rows over an advance, kept per step as what ``sensors.imu_rows`` needs (each (N,) or
    (N, 3)) and worked out for every step at once when the advance ends."""

    def __init__(self) -> None:
        super().__init__()
        self._inputs: list[tuple[np.ndarray, ...]] = []

    def add(self, stamp_us: int, rows: np.ndarray, silenced: np.ndarray | None = None) -> None:
        raise TypeError("ImuSteps keeps each step's inputs (add_inputs), not its rows")

    def add_inputs(self, stamp_us: int, inputs: tuple[np.ndarray, ...], silenced: np.ndarray | None = None) -> None:
        """Step ``stamp_us``'s speeds, forward accelerations and yaw rates (N,), gyro biases, gyro and
        accelerometer noise (N, 3), in ``sensors.imu_rows``' order."""
        self._stamps.append(stamp_us)
        self._inputs.append(inputs)
        self._silenced.append(silenced)

    def _stacked(self) -> np.ndarray:
        steps, vehicles = len(self._inputs), len(self._inputs[0][0])
        columns = [np.stack(column).reshape(steps * vehicles, *column[0].shape[1:]) for column in zip(*self._inputs)]
        return sensors.imu_rows(*columns).reshape(steps, vehicles, 6)


class HighRateSensors:
    """The IMU and wheels of N vehicles: what they carry from step to step (the gyro biases (N, 3)
    rad/s, the previous step's true speeds (N,) m/s, when each wheel slip ends (N,) us) and the
    current block's draws of every vehicle, stacked (N, steps, ...)."""

    def __init__(
        self, gyro_bias: np.ndarray, odom_scale: np.ndarray, step_us: int, odom_period_us: int, truth: SensorTruth
    ) -> None:
        self.gyro_bias, self.odom_scale = gyro_bias, odom_scale
        self.step_us, self.odom_period_us, self.truth = step_us, odom_period_us, truth
        self.last_speed = np.zeros(len(odom_scale))
        self.slip_until_us = np.full(len(odom_scale), -1, dtype=np.int64)
        self.block: dict[str, np.ndarray] = {}

    def new_block(self, noise: list[dict], errors: list[dict]) -> None:
        """The next block's draws: each vehicle's datasheet ``noise`` and hidden ``errors`` (sim.world,
        sim.true_errors), in vehicle order."""
        self.block = {
            "gyro": np.stack([d["gyro"] for d in noise]),
            "accel": np.stack([d["accel"] for d in noise]),
            "walk": np.stack([d["walk"] for d in noise]),
            Topic.ODOM: np.stack([d[Topic.ODOM] for d in noise]),
            "slip": np.stack([d["slip"] for d in errors]),
            "tail_odom": np.stack([d["tail_odom"] for d in errors]),
        }

    def step(
        self,
        streams: dict[str, ImuSteps | StepRows],
        t_us: int,
        k: int,
        speed: np.ndarray,
        yaw_rate: np.ndarray,
        silenced: Silenced,
    ) -> None:
        """Measure at step ``k`` of the block, stamped ``t_us``, from the true speeds and yaw rates
        (N,); the gyro biases walk on."""
        block = self.block
        accel_fwd = (speed - self.last_speed) / (self.step_us * 1e-6) if t_us else np.zeros(len(speed))
        self.last_speed = speed
        imu = (speed, accel_fwd, yaw_rate, self.gyro_bias, block["gyro"][:, k], block["accel"][:, k])
        streams[Topic.IMU].add_inputs(t_us, imu, silenced(Topic.IMU, t_us))
        self.gyro_bias = self.gyro_bias + block["walk"][:, k]
        if t_us % self.odom_period_us == 0:
            draws = OdometryDraws(self.odom_scale, block["slip"][:, k], block["tail_odom"][:, k])
            rows, self.slip_until_us = odometry_rows(
                self.truth,
                t_us,
                self.odom_period_us * 1e-6,
                speed,
                yaw_rate,
                block[Topic.ODOM][:, k],
                draws,
                self.slip_until_us,
            )
            streams[Topic.ODOM].add(t_us, rows, silenced(Topic.ODOM, t_us))
