"""Vehicle estimators: each is a ``Filter`` (vehicle.estimators.filter) composed of models, built by
one module per estimator (``build`` with explicit arguments, ``from_config`` from a vehicle's
configuration). ``get_estimator(config, vehicle_id)`` builds the one ``config.vehicle.estimator``
names, through the registry ``bus.estimators.ESTIMATORS``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable

from bus.config import VehicleProcessConfig
from bus.errors import ConfigError
from bus.estimators import ESTIMATORS
from vehicle.estimators.filter import Filter


def get_estimator(
    config: VehicleProcessConfig, vehicle_id: int, *, reject: Callable[[str, str, str], None] | None = None
) -> Filter:
    """The estimator a vehicle runs, built from its own configuration only; ``reject(reason, where,
    detail)`` counts input the estimator refuses (garbage camera frames)."""
    entry = ESTIMATORS.get(config.vehicle.estimator)
    if entry is None:
        raise ConfigError(f"unknown estimator {config.vehicle.estimator!r}; known: {', '.join(ESTIMATORS)}")
    return importlib.import_module(entry.module).from_config(config, vehicle_id, reject=reject)
