"""Run the centralized reference (``vehicle.centralized``) next to the pure world in one process and
score it against truth the way the ground station scores a run: per vehicle, position error and
pose NEES (3 dof) of the estimate at each scored stamp. No bus, no link faults: the yardstick is a
filter that hears every measurement at once."""

from __future__ import annotations

import numpy as np

from bus import feed
from bus.config import SwarmConfig
from groundstation.scoring import pose_error
from sim.world import World
from vehicle.centralized import CentralizedEkf

CHUNK_US = 1_000_000


def run_centralized(config: SwarmConfig, *, score_every_us: int = 200_000) -> dict[int, dict[str, np.ndarray]]:
    """The whole run of ``config`` through the centralized EKF: per vehicle ``t_s`` (k,), ``error_m``
    (k,) position error in m and ``nees`` (k,) pose NEES, every ``score_every_us`` of sim time."""
    world = World(config)
    ids = world.vehicle_ids()
    filt = CentralizedEkf(ids, spec=config.sensors, gate_probability=config.vehicle.gate_probability)
    period_us = round(1e6 / config.vehicle.loop_rate_hz)
    end_us = round(config.clock.duration_s * 1e6)
    rows: dict[int, list[tuple[float, float, float]]] = {vid: [] for vid in ids}
    pending: list = []
    t_us = 0
    while t_us <= end_us:
        chunk_end = min(end_us, world.now_us + CHUNK_US)
        out = world.advance(chunk_end)
        truth = dict(zip(out.truth_stamps, out.truth))
        samples = [s for vid in ids for s in feed.SensorBatch(vid, 0, chunk_end, out.blocks(vid)).samples()]
        pending += samples
        pending.sort(key=lambda item: item[1].stamp_us)  # stable: vehicles in id order at equal stamps
        i = 0
        while t_us <= chunk_end:
            while i < len(pending) and pending[i][1].stamp_us <= t_us:
                filt.handle(*pending[i])
                i += 1
            filt.cycle(t_us)
            if t_us % score_every_us == 0 and filt.initialized and t_us in truth:
                for k, vid in enumerate(ids):
                    error, nees = pose_error(*filt.pose(vid), truth[t_us][k, :3])
                    rows[vid].append((t_us * 1e-6, float(np.hypot(error[0], error[1])), nees))
            t_us += period_us
        pending = pending[i:]
    names = ("t_s", "error_m", "nees")
    return {vid: dict(zip(names, map(np.array, zip(*r)))) for vid, r in rows.items() if r}
