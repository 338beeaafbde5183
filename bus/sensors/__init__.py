"""The sensors added to the swarm by the sensor recipe: one module per sensor under bus/sensors/ and
one line in ``SENSORS`` (what a sensor declares: bus.sensors.base). The feed's layout, the messages
a vehicle unpacks, the datasheet's sections, link-fault topics and blackouts, the world's
measurements and the filters' parts come from here (docs/tutorial/adding-a-sensor.md)."""

from __future__ import annotations

from bus.sensors.base import SensorKind, SensorSpec
from bus.sensors.camera3d import Camera3d
from bus.sensors.compass import Compass

SENSORS: tuple[type[SensorKind], ...] = (Compass, Camera3d)
BY_TOPIC = {sensor.topic: sensor for sensor in SENSORS}

__all__ = ["BY_TOPIC", "SENSORS", "SensorKind", "SensorSpec"]
