"""Codec cost: one tick's sensor batch for a vehicle (columnar msgpack, decoded and unpacked as a
vehicle does: its IMU and wheel samples as runs of rows, the rest as messages; and every sample as a
message, as under link faults), the ground station's truth batch, and MAVLink 2 ODOMETRY
encode/decode, signed and not.

Targets: a vehicle's batch of one tick (1 s, some 175 samples) decoded and unpacked in <= 200 us; an
ODOMETRY frame encoded or decoded in <= 50 us. A realtime tick's batch (20 ms, 3 samples: its blocks
checked in plain Python, bus.feed_blocks) is measured warm, as here; a vehicle among forty processes
runs it cold, several times slower (docs/decisions/performance.md, fifteenth pass).
"""

from __future__ import annotations

import numpy as np

from bench.common import Row, per_call_us
from bus import feed
from bus.config import build_config
from bus.mavlink_codec import MavlinkDecoder, MavlinkEncoder, StateEstimate
from sim.world import World
from vehicle.process.input_runs import unpack

BATCH_US, FRAME_US = 200.0, 50.0


def _estimate(stamp_us: int) -> StateEstimate:
    cov = np.diag([0.2, 0.2, 1e-6, 1e-6, 1e-6, 0.01])
    return StateEstimate(3, stamp_us, np.array([1.0, 2.0, -30.0]), 0.3, np.zeros(3), 0.0, cov, np.eye(6))


def _batches(vehicles: int, mode: str = "lockstep", tick: int = 10) -> tuple[bytes, bytes, int]:
    """Tick ``tick`` of a ``vehicles`` swarm in ``mode`` (its tick's length): vehicle 1's encoded
    batch, the truth batch, samples in the batch."""
    config = build_config({"world": {"vehicles": vehicles, "seed": 1}, "clock": {"mode": mode}})
    world, tick_us = World(config), round(config.clock.tick_s * 1e6)
    world.advance(tick * tick_us - tick_us)
    out = world.advance(tick * tick_us)
    batch = feed.SensorBatch(1, tick, tick * tick_us, out.blocks(1))
    ids = world.vehicle_ids()
    rows = np.array(out.truth).reshape(len(out.truth_stamps), len(ids), feed.TRUTH_WIDTH)
    truth = feed.TruthBatch(tick, tick * tick_us, np.array(out.truth_stamps, dtype=np.int64), np.array(ids), rows)
    return feed.encode_batch(batch), feed.encode_truth(truth), len(batch.samples())


def run(quick: bool = False) -> list[Row]:
    calls = 2_000 if quick else 20_000
    payload, truth, samples = _batches(5)
    rows = []
    us = per_call_us(lambda: unpack(feed.decode_batch(payload), 0), calls=calls // 4)
    case = f"sensor batch, 1 tick ({samples} samples, {len(payload)} B)"
    rows.append(Row("codec", case, "decode + unpack", round(us, 1), "us", f"<= {BATCH_US:g} us", us <= BATCH_US))
    realtime, _, realtime_samples = _batches(5, "realtime", tick=11)  # between two ranging epochs
    us = per_call_us(lambda: unpack(feed.decode_batch(realtime), 0), calls=calls)
    realtime_case = f"sensor batch, 1 realtime tick ({realtime_samples} samples, {len(realtime)} B)"
    rows.append(Row("codec", realtime_case, "decode + unpack", round(us, 1), "us", "-", None))
    us = per_call_us(lambda: feed.decode_batch(payload).samples(), calls=calls // 4)
    rows.append(Row("codec", case, "decode + every sample a message (link faults)", round(us, 1), "us", "-", None))
    us = per_call_us(lambda: feed.decode_truth(truth), calls=calls // 4)
    rows.append(
        Row("codec", f"truth batch, 1 tick, 5 vehicles ({len(truth)} B)", "decode", round(us, 1), "us", "-", None)
    )
    key = bytes(range(32))
    for signed in (False, True):
        encoder = MavlinkEncoder(vehicle_id=3, signing_key=key if signed else None)
        frames = [encoder.odometry(_estimate(1000 * i)) for i in range(calls * 5 + 10)]  # signing: fresh timestamps
        decoder, it = MavlinkDecoder(signing_key=key if signed else None), iter(frames)
        label = "signed" if signed else "unsigned"
        for case, body in (
            (f"encode ODOMETRY ({label})", lambda e=encoder: e.odometry(_estimate(0))),
            (f"decode ODOMETRY ({label})", lambda d=decoder, i=it: d.decode(next(i))),
        ):
            us = per_call_us(body, calls=calls)
            rows.append(Row("codec", case, "per frame", round(us, 2), "us", f"<= {FRAME_US:g} us", us <= FRAME_US))
    return rows
