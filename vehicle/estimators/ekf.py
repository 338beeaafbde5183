"""``ekf``: the default vehicle estimator, an EKF over [x, y, theta, gyro_bias] driven by odometry
speed and gyro yaw rate (integrated between cycles: one prediction per loop cycle), GNSS-corrected
behind the GNSS health monitor, with cooperative (Covariance Intersection) updates from neighbours.
When the datasheet gives a time-correlated part of the GNSS error (``gnss_correlated_sigma_m``), the
state grows by that error's two Gauss-Markov states, [..., e_x, e_y] (6,). When it gives the wheel
odometry's scale uncertainty (``odom_scale_prior_sigma``), the state grows by the speed and yaw-rate
scale states after them (vehicle.estimators.persisting_errors), as ``known-map``'s does."""

from __future__ import annotations

from bus.config import SensorSpec, VehicleProcessConfig
from vehicle.estimators.divergence import FullCheck
from vehicle.estimators.filter import Filter
from vehicle.estimators.persisting_errors import GrowingErrors
from vehicle.estimators.settings import shared_arguments
from vehicle.estimators.stores import DenseStore
from vehicle.estimators.updates import Linearized
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
    store=None,
    monitor: MonitorSpec | None = MonitorSpec(),
) -> Filter:
    """The EKF of vehicle ``vehicle_id`` for the sensors of ``spec`` (module docstring); ``store``:
    where its state lives (default: plain arrays)."""
    error = GnssErrorModel.from_spec(spec)
    wheel_scales = bool(spec.odom_scale_prior_sigma)
    base_dim = UnicycleMotion(gnss_error=error).base_dim
    errors = GrowingErrors(spec, first_index=base_dim + 2, range_scale_index=None) if wheel_scales else None
    return Filter(
        name="ekf",
        vehicle_id=vehicle_id,
        spec=spec,
        gate_probability=gate_probability,
        gnss=gnss_model(error),
        motion=UnicycleMotion(gnss_error=error, wheel_scales=wheel_scales),
        update=Linearized(),
        store=DenseStore() if store is None else store,
        divergence=FullCheck(),
        errors=errors,
        cooperative=cooperative,
        adaptive_window=adaptive_window,
        monitor=monitor,
    )


def from_config(config: VehicleProcessConfig, vehicle_id: int, *, reject=None) -> Filter:
    """:func:`build` from a vehicle's configuration (``reject`` is unused: nothing is refused here)."""
    return build(**shared_arguments(config, vehicle_id))
