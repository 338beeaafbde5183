"""A vehicle restarted in flight has no launch-pad prior: it aligns from the GNSS track and the gyro.
Over seeded runs on every trajectory kind, the aligned filter is consistent (ANEES inside the
chi-square band) and within a metre or two of the truth."""

import numpy as np
from scipy.stats import chi2

from bus.config import build_config
from experiments.harness import samples_of
from sim.world import World
from vehicle.estimators import ekf

RUNS = 16
PERIOD_US = 20_000


def _restart(seed: int) -> tuple[list[float], list[float]]:
    """NEES and position error every second, from 2 s after alignment, of a filter started at ~7 s."""
    config = build_config(
        {"world": {"vehicles": 1, "seed": seed, "trajectories": [["circle", "figure8", "waypoints"][seed % 3]]}}
    )
    samples, truth = samples_of(World(config), 18_000_000)
    truth_at = {int(s): truth.rows[k, 0, :3] for k, s in enumerate(truth.stamps_us)}
    est = ekf.build(vehicle_id=1, spec=config.sensors, gate_probability=0.9995)
    start_us, aligned_us, nees, errors = 7_000_000 + 40_000 * seed, None, [], []
    samples = [(t, msg) for t, msg in samples if t not in ("prior", "ranging") and msg.stamp_us >= start_us]
    i = 0
    for t in range(start_us, 18_000_001, PERIOD_US):
        while i < len(samples) and samples[i][1].stamp_us <= t:
            est.handle(samples[i][1])
            i += 1
        est.cycle(t)
        if est.initialized and aligned_us is None:
            aligned_us = t
        if aligned_us is not None and t >= aligned_us + 2_000_000 and t % 1_000_000 == 0:
            d = est.x[:3] - truth_at[t]
            d[2] = (d[2] + np.pi) % (2 * np.pi) - np.pi
            nees.append(float(d @ np.linalg.solve(est.P[:3, :3], d)))
            errors.append(float(np.hypot(d[0], d[1])))
    assert aligned_us is not None and aligned_us - start_us < 4_000_000, "no alignment within 4 s"
    return nees, errors


def test_alignment_from_gnss_track_is_consistent_and_accurate():
    first = [_restart(seed) for seed in range(RUNS)]
    nees_at_first_sample = np.array([n[0] for n, _ in first])  # independent across runs
    low, high = chi2.ppf([0.025, 0.975], 3 * RUNS) / RUNS
    assert low <= nees_at_first_sample.mean() <= high
    assert max(e for _, errors in first for e in errors) < 3.0
    assert np.sqrt(np.mean([e**2 for _, errors in first for e in errors])) < 1.0
