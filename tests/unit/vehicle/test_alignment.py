"""A vehicle restarted in flight has no launch-pad prior: it aligns from the GNSS track and the gyro.
Over seeded runs on every trajectory kind, the aligned filter is consistent (ANEES inside the
chi-square band) and within a metre or two of the truth."""

import numpy as np
from scipy.stats import chi2

from bus import messages as m
from bus.config import build_config
from bus.keys import KeySpace
from sim.world import World
from vehicle.estimator import VehicleEstimator

TYPES = {"imu": m.ImuSample, "odom": m.WheelOdometry, "gnss": m.GnssFix, "prior": m.PosePrior,
         "truth": m.Truth, "ranging": m.RangeBearing}
RUNS = 16


def _restart(seed: int) -> tuple[list[float], list[float]]:
    """NEES and position error every second, from 2 s after alignment, of a filter started at 7 s."""
    config = build_config({"world": {"vehicles": 1, "seed": seed, "trajectories": [["circle", "figure8", "waypoints"][seed % 3]]}})
    world, keys = World(config), KeySpace()
    est = VehicleEstimator(vehicle_id=1, spec=config.sensors, gate_probability=0.9995, altitude_m=30.0)
    start_us, aligned_us, nees, errors = 7_000_000 + 37_000 * seed, None, [], []
    for key, payload in world.advance(18_000_000):
        msg = m.decode(TYPES[keys.topic_of(key)], payload)
        if isinstance(msg, m.Truth):
            if est.initialized and aligned_us is None:
                aligned_us = msg.stamp_us
            if aligned_us is not None and msg.stamp_us >= aligned_us + 2_000_000 and msg.stamp_us % 1_000_000 == 0:
                x, P = est.predicted(msg.stamp_us)
                d = x[:3] - msg.pose
                d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
                nees.append(float(d @ np.linalg.solve(P[:3, :3], d)))
                errors.append(float(np.hypot(d[0], d[1])))
        elif not isinstance(msg, (m.PosePrior, m.RangeBearing)) and msg.stamp_us >= start_us:
            est.handle(msg)
    assert aligned_us is not None and aligned_us - start_us < 4_000_000, "no alignment within 4 s"
    return nees, errors


def test_alignment_from_gnss_track_is_consistent_and_accurate():
    first = [_restart(seed) for seed in range(RUNS)]
    nees_at_first_sample = np.array([n[0] for n, _ in first])  # independent across runs
    low, high = chi2.ppf([0.025, 0.975], 3 * RUNS) / RUNS
    assert low <= nees_at_first_sample.mean() <= high
    assert max(e for _, errors in first for e in errors) < 3.0
    assert np.sqrt(np.mean([e**2 for _, errors in first for e in errors])) < 1.0
