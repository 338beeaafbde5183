"""What surviving faults costs, per operation, with no bus: the link-fault stage every receiving
process runs (per packet, idle and with delay and loss active), the fusion horizon's checkpoint per
50 Hz cycle (taken only where a late measurement is expected) and its replay when a measurement
arrives 300 ms late, and one Covariance Intersection update.

Targets: a packet through the stage <= 20 us with faults active (the bus itself costs about 30 us
per message in Python), a checkpoint <= 50 us (a quarter of the estimator's cycle), a 300 ms replay
<= 5 ms (a quarter of the 20 ms cycle), a CI update <= 500 us.
"""

from __future__ import annotations

import time

import numpy as np

from bench.common import Row, per_call_us
from bus.config import build_config
from bus.faults import Delay, Loss
from bus.link_faults import Arrival, LinkFaultStage
from experiments.harness import vehicle_feed
from vehicle.estimators import get_estimator
from vehicle.models.cooperative import CooperativeRule, cooperative_update
from vehicle.models.cooperative_fixes import CooperativeFix
from vehicle.process.fusion import FusionHorizon


def _stage_rows() -> list[Row]:
    idle = LinkFaultStage("v1", seed=1, faults=(Loss(name="other", dst="v2", percent=10),))
    busy = LinkFaultStage(
        "v1", seed=1, faults=(Loss(name="l", percent=10), Delay(name="d", delay_s=0.1, jitter_s=0.02))
    )
    counter = iter(range(10**9))

    def through(stage: LinkFaultStage) -> None:
        n = next(counter)
        stage.offer(Arrival("swarm/v/1/feed", "v1", "imu", n * 10_000, n))
        stage.release(n * 10_000)

    rows = []
    for label, stage, target in (("no fault selects it", idle, None), ("loss 10% + delay 100 +- 20 ms", busy, 20.0)):
        us = per_call_us(lambda: through(stage), calls=20_000)
        rows.append(
            Row(
                "faults",
                f"link stage, {label}",
                "per packet",
                round(us, 2),
                "us",
                f"<= {target:g} us" if target else "-",
                us <= target if target else None,
            )
        )
    return rows


def _fusion_run(feed: list, config, late_us: int) -> tuple[float, int]:
    """Wall time (s) of 3 s of 50 Hz cycles with every GNSS fix arriving ``late_us`` late, and the
    number of measurements fused late."""
    vconfig = config.for_vehicle()
    fusion = FusionHorizon(get_estimator(vconfig, 1), horizon_us=500_000)
    arrivals = sorted(
        ((msg.stamp_us + (late_us if topic == "gnss" else 0), i, topic, msg) for i, (topic, msg) in enumerate(feed)),
        key=lambda a: a[:2],
    )
    start, k = time.perf_counter(), 0
    for t in range(0, 3_400_001, 20_000):
        while k < len(arrivals) and arrivals[k][0] <= t:
            fusion.push(arrivals[k][2], arrivals[k][3])
            k += 1
        fusion.cycle(t)
    return time.perf_counter() - start, fusion.counters.late_fused


def _fusion_rows() -> list[Row]:
    config = build_config({"world": {"vehicles": 1, "seed": 1}, "clock": {"duration_s": 3.0}})
    feed = vehicle_feed(config)
    estimator = get_estimator(config.for_vehicle(), 1)
    estimator.handle(next(msg for topic, msg in feed if topic == "prior"))
    snapshot_us = per_call_us(estimator.snapshot, calls=2_000)
    on_time = min(_fusion_run(feed, config, 0)[0] for _ in range(3))
    late_runs = [_fusion_run(feed, config, 300_000) for _ in range(3)]
    replay_us = (min(t for t, _ in late_runs) - on_time) / late_runs[0][1] * 1e6
    return [
        Row(
            "faults",
            "fusion horizon checkpoint",
            "per checkpoint",
            round(snapshot_us, 1),
            "us",
            "<= 50 us",
            snapshot_us <= 50.0,
        ),
        Row(
            "faults",
            "fusion horizon replay, fix 300 ms late",
            "per late measurement",
            round(replay_us, 1),
            "us",
            "<= 5000 us",
            replay_us <= 5000.0,
        ),
    ]


def _ci_rows() -> list[Row]:
    """Cost of one cooperative fix per rule and weight (vehicle.models.cooperative), EKF linearization."""
    P = np.diag([1.0, 1.0, 0.01, 1e-6])
    fix = CooperativeFix(1, 0, 0, 2, 31.6, 0.02, np.diag([0.09, 0.0004]), np.array([30.0, 10.0]), np.eye(2) * 2.0)
    x = np.array([0.0, 0.0, 0.3, 0.0])
    rows = []
    for fusion, weight in (
        ("split-ci", "optimal"),
        ("split-ci", "closed-form"),
        ("ci", "optimal"),
        ("ci", "closed-form"),
        ("paper", "optimal"),
        ("naive", "optimal"),
    ):
        rule = CooperativeRule(fusion, weight)
        us = per_call_us(lambda: cooperative_update(x, P, fix, 1e9, rule), calls=2_000)
        rows.append(
            Row(
                "faults",
                f"cooperative fix, {fusion} / {weight}",
                "per ranging measurement",
                round(us, 1),
                "us",
                "<= 500 us",
                us <= 500.0,
            )
        )
    return rows


def run(quick: bool = False) -> list[Row]:
    return _stage_rows() + _fusion_rows() + _ci_rows()
