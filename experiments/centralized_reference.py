"""Run the centralized reference (``vehicle.estimators.centralized``) next to the world in one process (the
simulated world, or a data-set replay) and score it against truth the way the ground station scores
a run: per vehicle, position error and pose NEES (3 dof) of the estimate at each scored stamp where
truth is known. No bus, no link faults: the yardstick is a filter that hears every measurement at
once. Its blocks use the vehicles' estimator: ``known-map`` (with the configured map) or ``ekf``."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bus import statistics
from bus.config import SwarmConfig
from bus.consistency import consistency
from experiments import harness
from experiments.swarm_modes import SwarmModes, swarm_modes
from vehicle.estimators.centralized import CentralizedEkf
from vehicle.estimators.filter import Filter


def run_centralized(
    config: SwarmConfig,
    *,
    score_every_us: int = 200_000,
    world=None,
    estimator: Callable[..., Filter] | None = None,
    modes: list[tuple[float, SwarmModes]] | None = None,
) -> dict[int, dict[str, np.ndarray]]:
    """The whole run of ``config`` through the centralized EKF: per vehicle ``t_s`` (k,), ``error_m``
    (k,) position error in m and ``nees`` (k,) pose NEES, every ``score_every_us`` of sim time.
    ``world``: the world or replay to run (default: the one ``config`` describes); ``estimator``: the
    builder of the blocks' filters (default: the configured estimator's, vehicle.estimators);
    ``modes``: if given, receives (t s, experiments.swarm_modes.SwarmModes) at each scored stamp where
    every vehicle's truth is known."""
    if world is None:
        from sim.tick_output import make_world

        world = make_world(config)
    ids = world.vehicle_ids()
    blocks = _block_estimator(config)
    if estimator is not None:
        blocks["estimator"] = estimator
    filt = CentralizedEkf(ids, spec=config.sensors, gate_probability=config.vehicle.gate_probability, **blocks)
    rows: dict[int, list[tuple[float, float, float]]] = {vid: [] for vid in ids}

    def score(t_us: int, truth: np.ndarray | None) -> None:
        if t_us % score_every_us or not filt.initialized or truth is None:
            return
        for k, vid in enumerate(ids):
            if not np.isfinite(truth[k, 0]):  # a gap in the recorded truth
                continue
            pose, cov = filt.pose(vid)
            cov = statistics.published_pose_cov(cov, config.sensors.unmodelled_sigma_m)
            error = statistics.pose_error(pose, truth[k, :3])
            rows[vid].append((t_us * 1e-6, float(np.hypot(error[0], error[1])), statistics.nees(error, cov)))
        if modes is not None and np.all(np.isfinite(truth[:, 0])):
            errors = np.array([statistics.pose_error(filt.pose(vid)[0], truth[k, :3]) for k, vid in enumerate(ids)])
            modes.append((t_us * 1e-6, swarm_modes(errors, filt.poses_covariance())))

    period_us = round(1e6 / config.vehicle.loop_rate_hz)
    end_us = round(config.clock.duration_s * 1e6)
    harness.run(world, [harness.Listener(tuple(ids), filt)], end_us=end_us, period_us=period_us, on_cycle=score)
    names = ("t_s", "error_m", "nees")
    return {vid: dict(zip(names, map(np.array, zip(*r)))) for vid, r in rows.items() if r}


def _block_estimator(config: SwarmConfig) -> dict:
    """The vehicle estimator whose models the joint filter's blocks use, with its arguments."""
    if config.vehicle.estimator == "known-map":
        from vehicle.estimators import known_map

        return {"estimator": known_map.build, "landmarks": config.vehicle.landmarks}
    return {}


def tracks_summary(tracks: dict[int, dict[str, np.ndarray]]) -> dict:
    """Per vehicle and swarm: samples, RMSE and max position error (m), ANEES and the share of NEES
    inside its 95% chi-square band (3 dof), per vehicle the block ANEES and tail shares
    (bus.consistency), in the shape of summary.json's ``vehicles`` and ``swarm``."""
    low, high = statistics.chi2_band(statistics.POSE_NEES_DOF)
    vehicles = {}
    for vid, track in sorted(tracks.items()):
        error, nees = track["error_m"], track["nees"]
        vehicles[str(vid)] = {
            "samples": int(error.size),
            "rmse_m": round(float(np.sqrt(np.mean(error**2))), 6),
            "max_error_m": round(float(error.max()), 6),
            "anees": round(float(nees.mean()), 6),
            "nees_inside_95": round(float(np.mean((nees >= low) & (nees <= high))), 6),
            "consistency": consistency(track["t_s"], nees).as_dict(),
        }
    errors = np.concatenate([t["error_m"] for t in tracks.values()]) if tracks else np.zeros(0)
    nees = np.concatenate([t["nees"] for t in tracks.values()]) if tracks else np.zeros(0)
    swarm = {
        "samples": int(errors.size),
        "nees_dof": statistics.POSE_NEES_DOF,
        "nees_bounds_95": [round(float(low), 6), round(float(high), 6)],
        "rmse_m": round(math.sqrt(float(np.mean(errors**2))), 6) if errors.size else None,
        "anees": round(float(nees.mean()), 6) if nees.size else None,
    }
    return {"vehicles": vehicles, "swarm": swarm}
