"""``ekf-derated``: the EKF for a receiver whose reported covariance is known to be optimistic (the
tutorial docs/tutorial/adding-an-estimator.md walks through this module; examples/derated_gnss.py
shows that it works).

A receiver that reports 1.5 m while it really scatters 3 m makes the EKF over-confident: it fuses
every fix as if it were twice as good. The datasheet knows better, so the filter should fuse each
fix with the reported covariance times ``factor**2``. That is one new model (how a fix observes the
state) composed with the EKF's other parts, and a ``build`` function.
"""

from __future__ import annotations

import numpy as np

from bus.config import SensorSpec
from vehicle.estimators.divergence import FullCheck
from vehicle.estimators.filter import Filter
from vehicle.estimators.stores import DenseStore
from vehicle.estimators.updates import Linearized
from vehicle.models.gnss import Observed, WhiteGnss
from vehicle.models.motion import UnicycleMotion


class DeratedGnss(WhiteGnss):
    """fix = [x, y] + white noise with covariance ``factor**2`` times what the receiver reports."""

    def __init__(self, factor: float) -> None:
        if not factor >= 1.0:
            raise ValueError(f"a derating factor is at least 1, got {factor!r}")
        self.factor = factor

    def observe(self, x: np.ndarray, reported_cov_m2: np.ndarray) -> Observed:
        return Observed(x[:2], [0, 1], np.eye(2), reported_cov_m2 * self.factor**2)


def build(*, vehicle_id: int, spec: SensorSpec, gate_probability: float, factor: float = 2.0) -> Filter:
    """The EKF of ``vehicle.estimators.ekf`` with the derated GNSS model."""
    return Filter(
        name="ekf-derated",
        vehicle_id=vehicle_id,
        spec=spec,
        gate_probability=gate_probability,
        gnss=DeratedGnss(factor),
        motion=UnicycleMotion(),
        update=Linearized(),
        store=DenseStore(),
        divergence=FullCheck(),
    )


def from_config(config, vehicle_id: int, *, reject=None) -> Filter:
    """What ``vehicle.estimators.get_estimator`` calls once the registry names this module."""
    return build(vehicle_id=vehicle_id, spec=config.sensors, gate_probability=config.vehicle.gate_probability)
