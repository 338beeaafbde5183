"""The fusion horizon: late measurements are fused as if they had come on time; too late ones and
duplicates are counted, never fused."""

import numpy as np

from bus import messages as m
from bus.config import build_config
from bus.keys import KeySpace
from sim.world import World
from vehicle.estimator import VehicleEstimator
from vehicle.fusion import FusionHorizon

TYPES = {"imu": m.ImuSample, "odom": m.WheelOdometry, "gnss": m.GnssFix, "prior": m.PosePrior}
PERIOD_US = 20_000


def _feed(seconds: float, seed: int = 3) -> list[tuple[str, object]]:
    config = build_config({"world": {"vehicles": 1, "seed": seed}})
    keys = KeySpace()
    out = []
    for key, payload in World(config).advance(round(seconds * 1e6)):
        topic = keys.topic_of(key)
        if topic in TYPES:
            out.append((topic, m.decode(TYPES[topic], payload)))
    return out


def _run(arrivals: list[tuple[int, str, object]], horizon_us: int, end_us: int) -> tuple[VehicleEstimator, FusionHorizon]:
    """Cycle every 20 ms; at cycle t, push the measurements whose arrival time is <= t first."""
    config = build_config({})
    est = VehicleEstimator(vehicle_id=1, spec=config.sensors, gate_probability=0.9995, altitude_m=30.0)
    fusion = FusionHorizon(est, horizon_us=horizon_us)
    arrivals = sorted(arrivals, key=lambda a: a[0])
    i = 0
    for t in range(0, end_us + 1, PERIOD_US):
        while i < len(arrivals) and arrivals[i][0] <= t:
            fusion.push(arrivals[i][1], arrivals[i][2])
            i += 1
        fusion.cycle(t)
    return est, fusion


def test_late_measurements_inside_the_horizon_give_the_on_time_result():
    feed = _feed(6.0)
    on_time, _ = _run([(msg.stamp_us, topic, msg) for topic, msg in feed], 500_000, 6_000_000)
    # every GNSS fix and every 3rd odometry sample arrives 300 ms late
    late = [(msg.stamp_us + (300_000 if topic == "gnss" or (topic == "odom" and msg.seq % 3 == 0) else 0), topic, msg)
            for topic, msg in feed]
    delayed, fusion = _run(late, 500_000, 6_400_000)
    assert fusion.counters.late_fused > 30 and fusion.counters.replays > 0
    assert fusion.counters.dropped_stale == 0
    np.testing.assert_allclose(delayed.predicted(6_000_000)[0], on_time.predicted(6_000_000)[0], atol=1e-9)
    np.testing.assert_allclose(delayed.P, on_time.P, atol=1e-12)


def test_measurements_older_than_the_horizon_are_dropped_and_counted():
    feed = _feed(4.0)
    late = [(msg.stamp_us + (800_000 if topic == "gnss" else 0), topic, msg) for topic, msg in feed]
    _, fusion = _run(late, 500_000, 5_000_000)
    fixes = sum(1 for topic, _ in feed if topic == "gnss")
    assert fusion.counters.dropped_stale == fixes and fusion.counters.late_fused == 0


def test_duplicates_are_ignored_and_counted():
    feed = _feed(3.0)
    once, _ = _run([(msg.stamp_us, topic, msg) for topic, msg in feed], 500_000, 3_100_000)
    twice = [(msg.stamp_us, topic, msg) for topic, msg in feed]
    twice += [(msg.stamp_us + 40_000, topic, msg) for topic, msg in feed if topic in ("gnss", "odom")]
    doubled, fusion = _run(twice, 500_000, 3_100_000)
    assert fusion.counters.duplicates == sum(1 for topic, _ in feed if topic in ("gnss", "odom"))
    np.testing.assert_array_equal(doubled.x, once.x)
