"""The floor of a swarm run: the same world and the same estimators for the same vehicles, in one
process with no bus, no codecs, no MAVLink and no scoring. What the multi-process system costs on
top of this is the price of its shape (processes, zenoh, messages, signing, the ground station).

Each vehicle runs its real estimator behind its fusion horizon; cooperative fixes pair each ranging
measurement with the neighbour's estimate at the same stamp after the same 100 ms wait the vehicle
process uses, read straight from the neighbour's filter.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from bus.config import SwarmConfig
from bus.feed import SensorBatch
from bus.topics import Topic
from sim.world import World
from vehicle.estimators import get_estimator
from vehicle.models.cooperative_fixes import CooperativeFix
from vehicle.process.fusion import FusionHorizon


@dataclass
class FloorResult:
    wall_s: float  # the whole run
    estimator_s: float  # inside the vehicles' fusion horizons and estimators
    world_s: float  # inside the world
    cycles: int  # vehicle cycles run (all vehicles)

    @property
    def cycle_us(self) -> float:
        """Estimator work per vehicle cycle (fusion, prediction, updates), microseconds."""
        return self.estimator_s / self.cycles * 1e6


def run_floor(config: SwarmConfig) -> FloorResult:
    world, vconfig = World(config), config.for_vehicle()
    ids = world.vehicle_ids()
    estimators = {vid: get_estimator(vconfig, vid) for vid in ids}
    fusions = {
        vid: FusionHorizon(estimators[vid], horizon_us=round(vconfig.vehicle.fusion_horizon_s * 1e6)) for vid in ids
    }
    waiting: dict[int, list] = {vid: [] for vid in ids}
    broadcasts: dict[int, dict[int, tuple[np.ndarray, np.ndarray]]] = {vid: {} for vid in ids}
    tick_us, period_us = round(config.clock.tick_s * 1e6), round(1e6 / vconfig.vehicle.loop_rate_hz)
    latency_us, v2v_period_us = (
        round(vconfig.vehicle.cooperation.latency_s * 1e6),
        round(1e6 / config.sensors.ranging_rate_hz),
    )
    end_us = round(config.clock.duration_s * 1e6)
    estimator_s = world_s = 0.0
    cycles, next_cycle = 0, 0
    start = time.perf_counter()
    for stamp in range(0, end_us + 1, tick_us):
        t0 = time.perf_counter()
        out = world.advance(stamp)
        t1 = time.perf_counter()
        world_s += t1 - t0
        for vid in ids:
            for topic, msg in SensorBatch(vid, 0, stamp, out.blocks(vid)).samples():
                if topic is Topic.RANGING:
                    waiting[vid].append(msg)
                    fusions[vid].expect(msg.stamp_us)
                else:
                    fusions[vid].push(topic, msg)
        for t in range(next_cycle, stamp + 1, period_us):
            for vid in ids:
                ripe = [w for w in waiting[vid] if w.stamp_us + latency_us <= t]
                waiting[vid] = [w for w in waiting[vid] if w.stamp_us + latency_us > t]
                for msg in ripe:
                    heard = broadcasts[msg.target_id].get(msg.stamp_us)
                    if heard is not None:
                        fusions[vid].push(
                            Topic.RANGING,
                            CooperativeFix(
                                vid,
                                msg.stamp_us,
                                msg.seq,
                                msg.target_id,
                                msg.range_m,
                                msg.bearing_rad,
                                msg.covariance,
                                *heard,
                            ),
                        )
                fusions[vid].cycle(t)
                est = estimators[vid]
                if t % v2v_period_us == 0 and est.initialized:
                    broadcasts[vid][t] = (est.x[:2].copy(), est.P[:2, :2].copy())
                cycles += 1
            next_cycle = t + period_us
        estimator_s += time.perf_counter() - t1
    return FloorResult(time.perf_counter() - start, estimator_s, world_s, cycles)
