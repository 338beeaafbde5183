"""Vehicle estimators: each is a ``Filter`` (vehicle.estimators.filter) composed of models, built by
one module per estimator (``build`` with explicit arguments, ``from_config`` from a vehicle's
configuration). ``get_estimator(config, vehicle_id)`` builds the one ``config.vehicle.estimator``
names, ``build_estimator(name, **arguments)`` one by name with explicit arguments (experiments, the
centralized reference), both through the one registry ``bus.estimators.ESTIMATORS``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

from bus.config import VehicleProcessConfig
from bus.errors import ConfigError
from bus.estimators import ESTIMATORS
from bus.sensors import SENSORS
from bus.sensors.base import resolve
from vehicle.estimators.filter import Filter


def _module(name: str):
    entry = ESTIMATORS.get(name)
    if entry is None:
        raise ConfigError(f"unknown estimator {name!r}; known: {', '.join(ESTIMATORS)}")
    return importlib.import_module(entry.module)


def build_estimator(name: str, **arguments: Any) -> Filter:
    """The estimator the registry names ``name``, built by its module's ``build(**arguments)``."""
    return _module(name).build(**arguments)


def get_estimator(
    config: VehicleProcessConfig, vehicle_id: int, *, reject: Callable[[str, str, str], None] | None = None
) -> Filter:
    """The estimator a vehicle runs, built from its own configuration only; ``reject(reason, where,
    detail)`` counts input the estimator refuses (garbage camera frames)."""
    f = _module(config.vehicle.estimator).from_config(config, vehicle_id, reject=reject)
    for sensor in SENSORS:  # every sensor added by the recipe that this vehicle's datasheet has on
        spec = getattr(config.sensors, sensor.topic)
        if spec.rate_hz > 0:
            f.add_part(resolve(sensor.part)(config.sensors))
    return f
