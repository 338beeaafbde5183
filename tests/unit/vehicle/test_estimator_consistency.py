"""The vehicle EKF is consistent: NEES inside chi-square bounds over seeded Monte Carlo runs."""

import numpy as np
from scipy.stats import chi2

from bus.config import SensorSpec
from tests.offline import pose_nees_series

RUNS = 50
DOF = 3
KINDS = ("circle", "figure8", "waypoints")


def _monte_carlo(estimator_spec=None) -> np.ndarray:
    """(RUNS, steps) NEES, one seeded run each, trajectories cycling through every kind."""
    return np.array([pose_nees_series(seed, duration_s=20.0, trajectory=KINDS[seed % 3],
                                      estimator_spec=estimator_spec)[0] for seed in range(RUNS)])


def _fraction_inside_bounds(nees: np.ndarray) -> float:
    """Share of time steps whose run-averaged NEES lies in the two-sided 95% bounds (Bar-Shalom)."""
    lo, hi = chi2.ppf([0.025, 0.975], DOF * RUNS) / RUNS
    mean = nees.mean(axis=0)
    return float(np.mean((mean >= lo) & (mean <= hi)))


def test_nees_stays_inside_95_percent_bounds():
    nees = _monte_carlo()
    assert nees.shape == (RUNS, 21)  # t = 0, 1, ..., 20 s
    assert _fraction_inside_bounds(nees) >= 0.9
    lo, hi = chi2.ppf([0.025, 0.975], DOF * nees.size) / nees.size
    assert lo <= nees.mean() <= hi * 1.1  # time-correlated samples: allow a little slack on the grand mean


def test_the_check_catches_an_overconfident_filter():
    """Same harness, filter told its gyro is 20x better than it is: the bounds must be violated."""
    optimistic = SensorSpec(gyro_sigma_radps=0.0005, gyro_bias_sigma_radps=0.0005, gyro_bias_walk_radps_rtsec=0.0)
    assert _fraction_inside_bounds(_monte_carlo(optimistic)) < 0.5
