"""``ukf``: the default vehicle filter with the unscented transform where the models are nonlinear
(cooperative-localization paper: UKF, sigma points with lambda scaling). The same state, inputs, GNSS
health, divergence guard and fusion-horizon behaviour as ``ekf``; the ``Unscented`` update strategy
(vehicle.estimators.updates): every sigma point follows the exact arc of the inputs, the heading's
mean is circular, and neighbours' fixes go through sigma points of the pose marginal."""

from __future__ import annotations

from bus.config import SensorSpec, VehicleProcessConfig
from vehicle.estimators.divergence import FullCheck
from vehicle.estimators.filter import Filter
from vehicle.estimators.settings import shared_arguments
from vehicle.estimators.stores import DenseStore
from vehicle.estimators.updates import Unscented
from vehicle.models.cooperative import CooperativeRule
from vehicle.models.gnss import gnss_model
from vehicle.models.gnss_error import GnssErrorModel
from vehicle.models.motion import UnicycleMotion
from vehicle.trust.neighbours import MonitorSpec


def build(
    *,
    vehicle_id: int,
    spec: SensorSpec,
    gate_probability: float,
    cooperative: CooperativeRule = CooperativeRule(),
    adaptive_window: int = 0,
    monitor: MonitorSpec | None = MonitorSpec(),
) -> Filter:
    """The UKF of vehicle ``vehicle_id`` for the sensors of ``spec`` (module docstring)."""
    error = GnssErrorModel.from_spec(spec)
    return Filter(
        name="ukf",
        vehicle_id=vehicle_id,
        spec=spec,
        gate_probability=gate_probability,
        gnss=gnss_model(error),
        motion=UnicycleMotion(gnss_error=error),
        update=Unscented(),
        store=DenseStore(),
        divergence=FullCheck(),
        cooperative=cooperative,
        adaptive_window=adaptive_window,
        monitor=monitor,
    )


def from_config(config: VehicleProcessConfig, vehicle_id: int, *, reject=None) -> Filter:
    """:func:`build` from a vehicle's configuration (``reject`` is unused: nothing is refused here)."""
    return build(**shared_arguments(config, vehicle_id))
