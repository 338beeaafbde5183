"""The settings every vehicle estimator takes from a vehicle's configuration, read in one place: its
id, its datasheet, its GNSS gate, its cooperative rule, IAE's window (0: off) and its neighbour
monitor's thresholds (None: off). An estimator's ``from_config`` adds only what is its own."""

from __future__ import annotations

from typing import Any

from bus.config import VehicleConfig, VehicleProcessConfig
from vehicle.models.cooperative import CooperativeRule
from vehicle.trust.neighbours import MonitorSpec


def monitor_spec(vehicle: VehicleConfig) -> MonitorSpec | None:
    """The neighbour monitor a vehicle's configuration asks for (None: the monitor off)."""
    monitor = vehicle.monitor
    if not monitor.enabled:
        return None
    return MonitorSpec(max_compromised=monitor.max_compromised, hearsay_over_evidence=monitor.rule == "quorum-only")


def shared_arguments(config: VehicleProcessConfig, vehicle_id: int) -> dict[str, Any]:
    """``build``'s arguments every estimator shares, from a vehicle's configuration."""
    vc = config.vehicle
    return {
        "vehicle_id": vehicle_id,
        "spec": config.sensors,
        "gate_probability": vc.gate_probability,
        "cooperative": CooperativeRule(vc.cooperation.fusion, vc.cooperation.weight),
        "adaptive_window": vc.adaptive.window if vc.adaptive.enabled else 0,
        "monitor": monitor_spec(vc),
    }
