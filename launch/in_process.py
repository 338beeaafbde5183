"""The in-process run: a world (or a data-set replay) feeding filters with no bus, in stamp order,
cycle by cycle at the vehicles' loop rate, so that the tests' Monte Carlo runs, the benchmarks, the
centralized reference and the replay's own calibration run filters the one same way
(experiments.harness builds its runs on it).

``run`` advances the world a chunk at a time; every ``Listener`` (a filter and the vehicles whose
samples it hears: one for a vehicle filter, all of them for the centralized reference) gets every
sample stamped at or before a cycle's time, in stamp order (vehicles in id order at equal stamps),
then the cycle; ``on_cycle(t_us, truth)`` sees the truth rows (N, 6) of that instant, when the world
has them. With ``wire`` the samples go through the wire format first (bus.feed), as a vehicle
process receives them.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from bus import feed, statistics
from vehicle.estimators.filter import Filter

PERIOD_US = 20_000  # the vehicles' default loop period (50 Hz)
CHUNK_US = 1_000_000


@dataclass(frozen=True)
class Listener:
    """A filter (``handle(msg)``, ``cycle(t_us)``) and the vehicles whose samples it hears."""

    vehicle_ids: tuple[int, ...]
    filter: Any


def samples(out: Any, vehicle_id: int, stamp_us: int, *, wire: bool = False, camera: bool = False) -> list:
    """One vehicle's samples (topic, message) of a world step's output, in stamp order; ``wire``:
    through the wire format and back; ``camera``: with its camera frames."""
    frames = out.camera(vehicle_id) if camera else None
    batch = feed.SensorBatch(vehicle_id, 0, stamp_us, out.blocks(vehicle_id), frames)
    return feed.decode_batch(feed.encode_batch(batch)).samples() if wire else batch.samples()


def run(
    world: Any,
    listeners: list[Listener],
    *,
    end_us: int,
    period_us: int = PERIOD_US,
    chunk_us: int = CHUNK_US,
    wire: bool = False,
    camera: bool = False,
    on_cycle: Callable[[int, np.ndarray | None], None] | None = None,
) -> None:
    """Cycles at 0, ``period_us``, ... up to ``end_us`` (module docstring)."""
    pending: list[list] = [[] for _ in listeners]
    t_us = chunk_end = 0
    while t_us <= end_us:
        chunk_end = min(end_us, chunk_end + chunk_us)
        out = world.advance(chunk_end)
        truth = dict(zip(out.truth_stamps, out.truth))
        heard = {vid for listener in listeners for vid in listener.vehicle_ids}
        by_vehicle = {vid: samples(out, vid, chunk_end, wire=wire, camera=camera) for vid in sorted(heard)}
        for stream, listener in zip(pending, listeners):
            stream += [s for vid in listener.vehicle_ids for s in by_vehicle[vid]]
            stream.sort(key=lambda item: item[1].stamp_us)  # stable: vehicles in id order at equal stamps
        taken = [0] * len(listeners)
        while t_us <= chunk_end:
            for k, (stream, listener) in enumerate(zip(pending, listeners)):
                while taken[k] < len(stream) and stream[taken[k]][1].stamp_us <= t_us:
                    listener.filter.handle(stream[taken[k]][1])
                    taken[k] += 1
                listener.filter.cycle(t_us)
            if on_cycle is not None:
                on_cycle(t_us, truth.get(t_us))
            t_us += period_us
        pending = [stream[k:] for stream, k in zip(pending, taken)]


def pose_score(f: Filter, truth_pose: np.ndarray) -> tuple[float, float]:
    """(pose NEES, position error m) of a filter's estimate against the truth pose (3,)."""
    error = statistics.pose_error(f.state.x[:3], truth_pose)
    cov = statistics.published_pose_cov(f.state.P[:3, :3], f.spec.unmodelled_sigma_m)
    return statistics.nees(error, cov), float(np.hypot(error[0], error[1]))


def replay_in_memory(
    config,
    data,
    *,
    every_us: int = 1_000_000,
    estimators: dict | None = None,
    scorer: Callable[[Any, np.ndarray], tuple[float, float]] = pose_score,
) -> dict[int, np.ndarray]:
    """A data-set replay (sim.replay) with every vehicle's filter in this process, no bus: per vehicle,
    rows [t us, position error m, pose NEES] every ``every_us`` where truth exists (``scorer(filter,
    truth pose)``: (NEES, error)). ``estimators`` replaces the configured ones (vehicle id -> filter)."""
    from sim.replay import ReplayWorld
    from vehicle.estimators import get_estimator

    world = ReplayWorld(config, data)
    vehicle_config = config.for_vehicle()
    estimators = estimators or {vid: get_estimator(vehicle_config, vid) for vid in world.vehicle_ids()}
    ids = world.vehicle_ids()
    rows: dict[int, list] = {vid: [] for vid in estimators}

    def score(t_us: int, truth: np.ndarray | None) -> None:
        if t_us % every_us or truth is None:
            return
        for vid, estimator in estimators.items():
            pose = truth[ids.index(vid), :3]
            if estimator.initialized and np.isfinite(pose[0]):
                nees, error = scorer(estimator, pose)
                rows[vid].append([t_us, error, nees])

    listeners = [Listener((vid,), e) for vid, e in estimators.items()]
    end_us = round(config.clock.duration_s * 1e6)
    run(world, listeners, end_us=end_us, chunk_us=PERIOD_US, on_cycle=score)
    return {vid: np.array(r).reshape(-1, 3) for vid, r in rows.items()}
