"""Vehicle estimators behind one interface (``vehicle.estimators.base.Estimator``); one module each.

``get_estimator(config, vehicle_id)`` picks the one named by ``config.vehicle.estimator``.
"""

from __future__ import annotations

from typing import Callable

from bus.config import VehicleProcessConfig
from bus.errors import ConfigError
from vehicle.cooperative import CooperativeRule
from vehicle.estimators.base import Estimator


def get_estimator(config: VehicleProcessConfig, vehicle_id: int, *,
                  reject: Callable[[str, str, str], None] | None = None) -> Estimator:
    """The estimator a vehicle runs, built from its own configuration only; ``reject(reason, where,
    detail)`` counts input the estimator refuses (garbage camera frames)."""
    name = config.vehicle.estimator
    rule = CooperativeRule(config.vehicle.cooperative_fusion, config.vehicle.ci_weight)
    window = config.vehicle.adaptive_window if config.vehicle.adaptive_noise else 0
    if name == "ekf":
        from vehicle.estimators.ekf import UnicycleEkf

        return UnicycleEkf(vehicle_id=vehicle_id, spec=config.sensors, gate_probability=config.vehicle.gate_probability,
                           altitude_m=config.altitude_m, cooperative=rule, adaptive_window=window)
    if name == "ukf":
        from vehicle.estimators.ukf import UnicycleUkf

        return UnicycleUkf(vehicle_id=vehicle_id, spec=config.sensors, gate_probability=config.vehicle.gate_probability,
                           altitude_m=config.altitude_m, cooperative=rule, adaptive_window=window)
    if name == "known-map":
        from vehicle.estimators.known_map import KnownMapEkf

        return KnownMapEkf(vehicle_id=vehicle_id, spec=config.sensors, gate_probability=config.vehicle.gate_probability,
                           altitude_m=config.altitude_m, cooperative=rule, adaptive_window=window,
                           landmarks=config.vehicle.landmarks)
    if name == "ekf-slam":
        from vehicle.estimators.ekf_slam import EkfSlam

        return EkfSlam(vehicle_id=vehicle_id, spec=config.sensors, gate_probability=config.vehicle.gate_probability,
                       altitude_m=config.altitude_m, detector=config.vehicle.features, reject=reject,
                       cooperative=rule, adaptive_window=window)
    raise ConfigError(f"unknown estimator {name!r}")
