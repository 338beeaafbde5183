"""Adding an estimator, shown to work: ``compare`` flies the plain EKF and ``ekf-derated``
(vehicle/estimators/derated_gnss.py) on the same seeded worlds whose receivers scatter twice their
reported sigma, and returns each one's ANEES (docs/tutorial/adding-an-estimator.md; the tests run
it). The comparison lives here, with the runner, so the estimator itself imports nothing of the
experiments (the layers contract).
"""

from __future__ import annotations

import numpy as np

from bus.config import build_config
from experiments.harness import Listener, pose_score, run
from sim.world import World
from vehicle.estimators import derated_gnss, ekf


def compare(seeds: range, *, duration_s: float = 30.0, factor: float = 2.0) -> dict[str, float]:
    """ANEES of the plain EKF and of the derated one on the same worlds, whose receivers scatter
    ``factor`` times their reported sigma (``world.sensor_truth.gnss_sigma_factor``)."""
    nees: dict[str, list[float]] = {"ekf": [], "ekf-derated": []}
    for seed in seeds:
        config = build_config({"world": {"vehicles": 1, "seed": seed, "sensor_truth": {"gnss_sigma_factor": factor}}})
        arguments = {"vehicle_id": 1, "spec": config.sensors, "gate_probability": config.vehicle.gate_probability}
        filters = {"ekf": ekf.build(**arguments), "ekf-derated": derated_gnss.build(**arguments, factor=factor)}

        def score(t_us: int, truth: np.ndarray | None) -> None:
            if t_us % 1_000_000 == 0 and t_us >= 5_000_000:  # every second, once the start is behind
                for name, f in filters.items():
                    nees[name].append(pose_score(f, truth[0, :3])[0])

        listeners = [Listener((1,), f) for f in filters.values()]
        run(World(config), listeners, end_us=round(duration_s * 1e6), on_cycle=score)
    return {name: float(np.mean(values)) for name, values in nees.items()}


if __name__ == "__main__":
    print(compare(range(1, 11)))
