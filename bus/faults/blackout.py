"""``blackout``: one sensor of one vehicle stays silent."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from bus.faults.base import ChaosSwarm, FaultBase, cli, vehicle_field
from bus.sensors import BY_TOPIC
from bus.topics import Topic

_MADE = (Topic.IMU, Topic.ODOM, Topic.GNSS, Topic.RANGING, Topic.LANDMARK, Topic.CAMERA)  # by the world (or a replay)
SENSORS = tuple(map(str, _MADE)) + tuple(BY_TOPIC)  # and the sensors added by the recipe
CHAOS_SENSORS = tuple(str(t) for t in (Topic.IMU, Topic.ODOM, Topic.GNSS, Topic.RANGING))  # every vehicle has these


class Blackout(FaultBase):
    """One sensor of one vehicle stays silent."""

    effect: ClassVar[str] = "one sensor of one vehicle is silent"

    kind: Literal["blackout"] = "blackout"
    vehicle: int = vehicle_field()
    sensor: Literal[SENSORS] = Field(  # type: ignore[valid-type]
        description="the silent sensor: " + ", ".join(SENSORS), json_schema_extra=cli("--sensor", "text", "gnss")
    )

    def silences(self, vehicle_id: int, sensor: str, xy_m: np.ndarray) -> bool:
        return vehicle_id == self.vehicle and sensor == self.sensor

    @classmethod
    def chaos(cls, rng: np.random.Generator, swarm: ChaosSwarm) -> dict[str, Any]:
        return {"vehicle": int(rng.integers(1, swarm.vehicles + 1)), "sensor": str(rng.choice(CHAOS_SENSORS))}
