"""``compass``: a magnetometer's heading. The example of the recipe for a sensor
(docs/tutorial/adding-a-sensor.md): this module, one line in bus.sensors, the world's model of it
(sim/sensor_models/compass.py) and the filter part that fuses it (vehicle/estimators/compass.py)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from pydantic import Field

from bus.sensors.base import SensorKind, SensorSpec


class CompassSpec(SensorSpec):
    rate_hz: float = Field(0.0, ge=0, le=100, description="heading fixes per second (0: no compass)")
    sigma_rad: float = Field(0.05, gt=0, le=1.0, description="its heading noise (rad)")


@dataclass(frozen=True)
class CompassHeading:
    """The vehicle's heading (rad, the filter's convention) with its variance (rad^2)."""

    vehicle_id: int
    stamp_us: int
    seq: int
    heading_rad: float
    variance_rad2: float


class Compass(SensorKind):
    topic: ClassVar[str] = "compass"
    width: ClassVar[int] = 2  # heading rad, variance rad^2
    max_rows: ClassVar[int] = 1000
    max_abs: ClassVar[float] = 10.0
    Spec: ClassVar[type[SensorSpec]] = CompassSpec
    world_model: ClassVar[str] = "sim.sensor_models.compass:measure"
    part: ClassVar[str] = "vehicle.estimators.compass:CompassPart"

    @classmethod
    def message(cls, vehicle_id: int, stamp_us: int, seq: int, row: np.ndarray) -> CompassHeading:
        return CompassHeading(vehicle_id, stamp_us, seq, float(row[0]), float(row[1]))

    @classmethod
    def flaw(cls, rows: np.ndarray) -> str | None:
        if not (rows[:, 1] > 0).all() or not (np.abs(rows[:, 0]) <= math.pi + 1e-9).all():
            return "a heading within +-pi rad and a positive variance"
        return None
