"""Codec cost per message: msgpack sensor decode and MAVLink 2 ODOMETRY encode/decode (signed and not).

Target: every bus message costs <= 50 us to decode, so a 5-vehicle swarm's ~1,300 messages per sim
second take < 7% of one core at 1x.
"""

from __future__ import annotations

import numpy as np

from bench.common import Row, per_call_us
from bus import messages as m
from bus.mavlink_codec import MavlinkDecoder, MavlinkEncoder, StateEstimate

TARGET_US = 50.0


def _estimate() -> StateEstimate:
    cov = np.diag([0.2, 0.2, 1e-6, 1e-6, 1e-6, 0.01])
    return StateEstimate(3, 1_000_000, np.array([1.0, 2.0, -30.0]), 0.3, np.zeros(3), 0.0, cov, np.eye(6))


def run(quick: bool = False) -> list[Row]:
    calls = 2_000 if quick else 20_000
    rng = np.random.default_rng(0)
    imu = m.encode(m.ImuSample(1, 10_000, 1, rng.normal(size=3), rng.normal(size=3)))
    gnss = m.encode(m.GnssFix(1, 10_000, 1, rng.normal(size=2), np.eye(2) * 2.25))
    key = bytes(range(32))
    cases = {
        "decode ImuSample (msgpack)": lambda: m.decode(m.ImuSample, imu),
        "decode GnssFix (msgpack)": lambda: m.decode(m.GnssFix, gnss),
    }
    for signed in (False, True):
        encoder = MavlinkEncoder(vehicle_id=3, signing_key=key if signed else None)
        frames = [encoder.odometry(_estimate()) for _ in range(calls * 5 + 10)]  # signing needs fresh timestamps
        decoder = MavlinkDecoder(signing_key=key if signed else None)
        it = iter(frames)
        label = "signed" if signed else "unsigned"
        cases[f"encode ODOMETRY ({label})"] = lambda e=encoder: e.odometry(_estimate())
        cases[f"decode ODOMETRY ({label})"] = lambda d=decoder, i=it: d.decode(next(i))
    rows = []
    for case, body in cases.items():
        value = per_call_us(body, calls=calls)
        rows.append(Row("codec", case, "per message", round(value, 2), "us", f"<= {TARGET_US:g} us", value <= TARGET_US))
    return rows
