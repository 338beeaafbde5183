"""A swarm of ``ar-ekf-slam-3d`` vehicles flown in one process (launch.in_process: the pure world
feeding each vehicle's estimator its own samples, cycle by cycle at the vehicles' loop rate, no bus):
what the unit tests and the Monte Carlo of tools/uav3d.py measure, where the processes would add
nothing but time. Scored as the ground station scores the processes' estimates: the horizontal error
of the published pose and its 2-dof NEES, and the published height's error against the truth's height
above the launch point, with its 1-dof NEES."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bus.config import SwarmConfig
from launch.in_process import Listener, run
from vehicle.estimators import get_estimator


@dataclass(frozen=True)
class FlightScore:
    """One vehicle's flight, sampled every ``every_us``: times (k,) s, horizontal error (k,) m, the
    published position's NEES (k,) (2 dof), its counters at the end (resets, landmarks fused), and
    the published height's error (k,) m with its NEES (k,) (1 dof)."""

    t_s: np.ndarray
    error_m: np.ndarray
    nees: np.ndarray
    resets: int
    fused: int
    height_error_m: np.ndarray
    height_nees: np.ndarray

    @property
    def height_rmse_m(self) -> float:
        return float(np.sqrt(np.mean(self.height_error_m**2)))

    @property
    def rmse_m(self) -> float:
        return float(np.sqrt(np.mean(self.error_m**2)))

    @property
    def anees(self) -> float:
        return float(np.mean(self.nees))


def fly_in_process(config: SwarmConfig, *, every_us: int = 1_000_000) -> dict[int, FlightScore]:
    """Every vehicle of ``config`` flown for its ``clock.duration_s`` (module docstring)."""
    from sim.world import World

    world = World(config)
    vehicle_config = config.for_vehicle()
    ids = world.vehicle_ids()
    estimators = {vid: get_estimator(vehicle_config, vid) for vid in ids}
    rows: dict[int, list[tuple[float, float, float, float, float]]] = {vid: [] for vid in ids}

    def score(t_us: int, truth: np.ndarray | None) -> None:
        if truth is None or t_us % every_us:
            return
        for vid, true_pose in zip(ids, truth):
            estimator = estimators[vid]
            if not estimator.initialized:
                continue
            published = estimator.estimate(t_us)
            error = published.pose[:2] - true_pose[:2]
            nees = float(error @ np.linalg.solve(published.pose_cov[:2, :2], error))
            height_error = published.altitude.height_m - float(true_pose[5])  # bus.feed.TruthBatch's height
            height_nees = height_error**2 / published.altitude.var
            rows[vid].append((t_us * 1e-6, float(np.hypot(*error)), nees, height_error, height_nees))

    listeners = [Listener((vid,), estimators[vid]) for vid in ids]
    run(world, listeners, end_us=round(config.clock.duration_s * 1e6), on_cycle=score)
    out = {}
    for vid in ids:
        t_s, error_m, nees, height_error, height_nees = (np.array(column) for column in zip(*rows[vid]))
        counters = estimators[vid].counters
        fused = estimators[vid].state.slam.book.fused
        out[vid] = FlightScore(t_s, error_m, nees, counters.resets, fused, height_error, height_nees)
    return out
