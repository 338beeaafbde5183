"""A vehicle process's own work per simulated second, alone on a core: every vehicle node of an
N-vehicle swarm in this one process over the in-memory bus (bus.memory), fed the world's encoded
sensor batches and clock ticks at 50 Hz and each other's V2V broadcasts, as the real processes are.
Thread CPU time is split into filing (decoding and sorting what arrives: batches, ticks, the
neighbours' broadcasts) and the cycle (fusion, estimator, MAVLink encode, signing, publish).

Set against the CPU a vehicle uses in a real realtime swarm (bench_swarm), it shows what contention
for the 2 cores (35 processes, their zenoh threads, caches) adds to the same work.
"""

from __future__ import annotations

import time

from bench.common import Row
from bus import feed
from bus import messages as m
from bus.config import build_config
from bus.memory import MemoryHub
from sim.world import World
from vehicle.process.node import VehicleNode

CASES = (5, 20, 32)


def measure(vehicles: int, duration_s: float, *, seed: int = 1) -> dict:
    """Filing and cycle CPU (ms per vehicle per simulated second) of ``vehicles`` nodes over ``duration_s``."""
    config = build_config(
        {"world": {"vehicles": vehicles, "seed": seed}, "clock": {"mode": "realtime", "duration_s": duration_s}}
    )
    hub, world = MemoryHub(), World(config)
    nodes = [VehicleNode(hub.connect("vehicle"), config.for_vehicle(), vid) for vid in world.vehicle_ids()]
    keys, tick_us = nodes[0].bus.keys, round(config.clock.tick_s * 1e6)
    filing = cycling = 0.0
    for tick in range(round(duration_s * 1e6) // tick_us + 1):
        stamp = tick * tick_us
        out = world.advance(stamp)
        for vid in world.vehicle_ids():
            hub.deliver(
                keys.feed(vid), feed.encode_batch(feed.SensorBatch(vid, tick, stamp, out.blocks(vid), out.camera(vid)))
            )
        hub.deliver(keys.clock(), m.encode(m.ClockTick(tick, stamp, time.time_ns(), False)))
        for node in nodes:
            start = time.thread_time()
            item = node.mailbox.get_nowait()
            while item is not None:
                node.take(item)
                item = node.mailbox.get_nowait()
            middle = time.thread_time()
            for t_us in node.cycles_due(stamp):
                node.cycle(t_us)
                node.report(t_us)
                node.outbound.flush()
            filing, cycling = filing + middle - start, cycling + time.thread_time() - middle
    per = 1e3 / (vehicles * duration_s)
    fused = sum(node.estimator.counters.v2v_fused for node in nodes)
    return {
        "vehicles": vehicles,
        "sim_s": duration_s,
        "filing_ms": filing * per,
        "cycle_ms": cycling * per,
        "total_ms": (filing + cycling) * per,
        "v2v_fused": fused,
    }


def run(quick: bool = False) -> list[Row]:
    rows = []
    for vehicles in CASES[:1] if quick else CASES:
        print(f"  vehicle: {vehicles} nodes in one process ...", flush=True)
        r = measure(vehicles, 5.0 if quick else 20.0)
        case = f"one vehicle's work alone, swarm of {vehicles}"
        rows.append(Row("vehicle", case, "CPU per simulated second", round(r["total_ms"], 2), "ms", "-", None, r))
        rows.append(
            Row("vehicle", case, "of which filing (batches, ticks, V2V)", round(r["filing_ms"], 2), "ms", "-", None)
        )
    return rows


if __name__ == "__main__":
    for n in CASES:
        print(measure(n, 10.0))
