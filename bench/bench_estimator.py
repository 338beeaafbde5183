"""Estimator core cost with no bus: one vehicle's 100 Hz IMU, 50 Hz odometry and 5 Hz GNSS through the
default estimator behind its fusion horizon, one cycle (prediction with the inputs integrated since
the last one, then the updates) every 20 ms, as the vehicle process runs it.

Target: a 50 Hz cycle well under 100 us (a quarter of the 20 ms cycle shared by 100 vehicles on two
cores would be 100 us); held to <= 50 us. The UKF variant and the EKF
with the GNSS error states (the honest datasheet) side by side.
"""

from __future__ import annotations

import time

from bench.common import Row
from bus.config import HONEST_DATASHEET, build_config
from experiments.harness import vehicle_feed
from vehicle.estimators import get_estimator
from vehicle.process.fusion import FusionHorizon

TARGET_US = 50.0


def cycle_us(duration_s: float, repeats: int = 3, estimator: str = "ekf", sensors: dict | None = None) -> float:
    """Best-of-``repeats`` estimator time per 50 Hz cycle [us] for one non-cooperative vehicle
    (``sensors``: datasheet overrides, e.g. the GNSS error states)."""
    config = build_config(
        {
            "world": {"vehicles": 1, "seed": 1},
            "clock": {"duration_s": duration_s},
            "vehicle": {"estimator": estimator},
            "sensors": sensors or {},
        }
    )
    vconfig = config.for_vehicle()
    feed = vehicle_feed(config)
    period_us = round(1e6 / vconfig.vehicle.loop_rate_hz)
    best = float("inf")
    for _ in range(repeats):
        fusion = FusionHorizon(get_estimator(vconfig, 1), horizon_us=round(vconfig.vehicle.fusion_horizon_s * 1e6))
        k, cycles = 0, 0
        start = time.perf_counter()
        for t in range(0, round(duration_s * 1e6) + 1, period_us):
            while k < len(feed) and feed[k][1].stamp_us <= t:
                fusion.push(*feed[k])
                k += 1
            fusion.cycle(t)
            cycles += 1
        best = min(best, (time.perf_counter() - start) / cycles)
    return best * 1e6


def run(quick: bool = False) -> list[Row]:
    us = cycle_us(10 if quick else 60)
    ukf_us = cycle_us(10 if quick else 60, estimator="ukf")
    gnss_states_us = cycle_us(10 if quick else 60, sensors=HONEST_DATASHEET)
    return [
        Row(
            "estimator",
            "EKF [x, y, yaw, gyro bias] + fusion horizon, 1 vehicle",
            "per 50 Hz cycle",
            round(us, 1),
            "us",
            f"<= {TARGET_US:g} us",
            us <= TARGET_US,
        ),
        Row(
            "estimator",
            "UKF, same state and inputs + fusion horizon, 1 vehicle",
            "per 50 Hz cycle",
            round(ukf_us, 1),
            "us",
            "-",
            None,
            {"ukf_over_ekf": round(ukf_us / us, 1)},
        ),
        Row(
            "estimator",
            "EKF with the two GNSS error states (HONEST_DATASHEET), 1 vehicle",
            "per 50 Hz cycle",
            round(gnss_states_us, 1),
            "us",
            "-",
            None,
            {"over_ekf": round(gnss_states_us / us, 1)},
        ),
    ]
