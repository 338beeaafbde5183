"""Adding an estimator: ``ekf-derated``, the EKF for a receiver whose reported covariance is known to
be optimistic (docs/tutorial/adding-an-estimator.md walks through this file; the tests run it).

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


def compare(seeds: range, *, duration_s: float = 30.0, factor: float = 2.0) -> dict[str, float]:
    """ANEES of the plain EKF and of the derated one on the same worlds, whose receivers scatter
    ``factor`` times their reported sigma (``world.sensor_truth.gnss_sigma_factor``)."""
    from bus.config import build_config
    from experiments.harness import Listener, pose_score, run
    from sim.world import World
    from vehicle.estimators import ekf

    nees: dict[str, list[float]] = {"ekf": [], "ekf-derated": []}
    for seed in seeds:
        config = build_config({"world": {"vehicles": 1, "seed": seed, "sensor_truth": {"gnss_sigma_factor": factor}}})
        arguments = {"vehicle_id": 1, "spec": config.sensors, "gate_probability": config.vehicle.gate_probability}
        filters = {"ekf": ekf.build(**arguments), "ekf-derated": build(**arguments, factor=factor)}

        def score(t_us: int, truth: np.ndarray | None) -> None:
            if t_us % 1_000_000 == 0 and t_us >= 5_000_000:  # every second, once the start is behind
                for name, f in filters.items():
                    nees[name].append(pose_score(f, truth[0, :3])[0])

        listeners = [Listener((1,), f) for f in filters.values()]
        run(World(config), listeners, end_us=round(duration_s * 1e6), on_cycle=score)
    return {name: float(np.mean(values)) for name, values in nees.items()}


if __name__ == "__main__":
    print(compare(range(1, 11)))
