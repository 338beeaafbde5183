"""The ``ekf-slam`` estimator on the world's own camera frames (no bus): the map grows, re-observing
the start area (a loop closure) shrinks the pose covariance, garbage frames are refused and
reported once, and a fusion-horizon replay reproduces the state exactly."""

import numpy as np
import pytest

from bus import messages as m
from bus.config import build_config
from experiments.harness import vehicle_feed
from vehicle.estimators import get_estimator

CYCLE_US = 20_000


def _config(duration_s: float):
    return build_config(
        {
            "world": {"vehicles": 1, "seed": 4, "trajectories": ["circle"], "terrain_size_px": 640},
            "clock": {"duration_s": duration_s},
            "sensors": {"camera_rate_hz": 10},
            "vehicle": {"estimator": "ekf-slam", "cooperation": {"enabled": False}},
            "faults": [{"kind": "jam-gnss", "center_m": [0.0, 0.0], "radius_m": 1000.0}],
        }
    )


def _run(estimator, feed, start_us: int, end_us: int, index: int = 0, every_us: int = 1_000_000):
    """Feed and cycle from start_us to end_us; returns the next feed index and {t: sqrt(tr P_xy)}."""
    sigma = {}
    for t in range(start_us, end_us + 1, CYCLE_US):
        while index < len(feed) and feed[index][1].stamp_us <= t:
            estimator.handle(feed[index][1])
            index += 1
        estimator.cycle(t)
        if t % every_us == 0:
            sigma[t] = float(np.sqrt(estimator.P[0, 0] + estimator.P[1, 1]))
    return index, sigma


@pytest.fixture(scope="module")
def circle_run():
    config = _config(40)
    estimator = get_estimator(config.for_vehicle(), 1)
    _, sigma = _run(estimator, vehicle_feed(config), 0, 40_000_000)
    return estimator, sigma


def test_the_map_grows_with_the_ground_covered(circle_run):
    estimator, _ = circle_run
    c = estimator.counters
    assert c.frames_used == 401 and c.landmarks >= 40
    assert estimator.state.landmarks.descriptors.shape[0] == c.landmarks and len(estimator.x) == 4 + 2 * c.landmarks
    P = estimator.P
    assert np.allclose(P, P.T, atol=1e-9) and np.linalg.eigvalsh(P).min() > 0


def test_re_observing_the_start_area_shrinks_the_pose_covariance(circle_run):
    """The 20 m circle at 4 m/s closes after ~31 s: the uncertainty grown over the first lap falls
    once the first landmarks are seen again (with no GNSS at all), and on the second lap it stays
    within the first lap's, bounded by the map (dead reckoning's grows without bound)."""
    _, sigma = circle_run
    first_lap = [sigma[t] for t in range(0, 29_000_001, 1_000_000)]
    closed = min(sigma[t] for t in range(30_000_000, 33_000_001, 1_000_000))
    second_lap = [sigma[t] for t in range(33_000_000, 40_000_001, 1_000_000)]
    assert closed < 0.6 * max(first_lap[20:]) and closed < 1.2 * sigma[0]
    assert max(second_lap) < max(first_lap)


def test_garbage_frames_are_refused_and_reported_once_even_when_replayed():
    config = _config(2)
    refused = []
    estimator = get_estimator(config.for_vehicle(), 1, reject=lambda *args: refused.append(args))
    feed = [(t, msg) for t, msg in vehicle_feed(config) if t != "camera"]
    index, _ = _run(estimator, feed, 0, 100_000)
    snapshot = estimator.snapshot()
    garbage = [
        np.zeros((80, 80), np.uint8),
        np.full((80, 80), 128, np.uint8),
        np.zeros((80, 80), np.float32),
        np.zeros((80, 40), np.uint8),
        np.zeros((0, 0), np.uint8),
    ]
    for k, pixels in enumerate(garbage):
        estimator.handle(m.CameraFrame(1, 120_000 + k, 100 + k, pixels, 0.1))
    estimator.restore(snapshot)  # a replay meets the same frames again
    for k, pixels in enumerate(garbage):
        estimator.handle(m.CameraFrame(1, 120_000 + k, 100 + k, pixels, 0.1))
    assert [r[0] for r in refused] == ["garbage_frame"] * 5
    assert {r[2] for r in refused} == {
        "all black",
        "no texture (uniform grey)",
        "not a square grey uint8 frame",
        "empty frame",
    }
    assert estimator.counters.frames_used == 0 and estimator.counters.landmarks == 0
    _run(estimator, feed, 140_000, 200_000, index)  # the loop goes on
    assert np.isfinite(estimator.x).all()


def test_a_replay_from_a_snapshot_reproduces_the_state_exactly():
    config = _config(12)
    feed = vehicle_feed(config)
    estimator = get_estimator(config.for_vehicle(), 1)
    index, _ = _run(estimator, feed, 0, 8_000_000)
    snapshot = estimator.snapshot()
    _run(estimator, feed, 8_020_000, 12_000_000, index)
    first = estimator.x.copy(), estimator.P.copy(), estimator.counters.landmarks
    estimator.restore(snapshot)
    _run(estimator, feed, 8_020_000, 12_000_000, index)
    assert first[2] == estimator.counters.landmarks > 0
    assert np.array_equal(first[0], estimator.x) and np.array_equal(first[1], estimator.P)
