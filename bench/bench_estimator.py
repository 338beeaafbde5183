"""Estimator core cost with no bus: one vehicle's 100 Hz IMU, 50 Hz odometry and 5 Hz GNSS through the
EKF, plus one published estimate per 20 ms cycle.

Target: <= 1 ms of estimator work per 50 Hz cycle (5% of the 20 ms budget).
"""

from __future__ import annotations

import time

from bench.common import Row
from bus import messages as m
from bus.config import build_config
from bus.keys import KeySpace
from sim.world import World
from vehicle.estimator import VehicleEstimator

TARGET_US = 1000.0
TYPES = {"imu": m.ImuSample, "odom": m.WheelOdometry, "gnss": m.GnssFix, "prior": m.PosePrior}


def run(quick: bool = False) -> list[Row]:
    duration_s = 10 if quick else 60
    config = build_config({"world": {"vehicles": 1, "seed": 1}})
    keys = KeySpace()
    messages = [m.decode(TYPES[keys.topic_of(k)], p) for k, p in World(config).advance(duration_s * 1_000_000)
                if keys.topic_of(k) in TYPES]
    best = float("inf")
    for _ in range(3):
        estimator = VehicleEstimator(vehicle_id=1, spec=config.sensors, gate_probability=0.9995, altitude_m=30.0)
        next_cycle = 0
        start = time.perf_counter()
        for msg in messages:
            while msg.stamp_us > next_cycle and estimator.initialized:
                estimator.estimate(next_cycle)
                next_cycle += 20_000
            estimator.handle(msg)
        best = min(best, time.perf_counter() - start)
    per_cycle = best / (duration_s * 50) * 1e6
    return [Row("estimator", "EKF [x, y, yaw, gyro bias], 1 vehicle", "per 50 Hz cycle", round(per_cycle, 1), "us",
                f"<= {TARGET_US:g} us", per_cycle <= TARGET_US)]
