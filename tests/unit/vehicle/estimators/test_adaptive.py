"""IAE (vehicle.estimators.adaptive): the window's estimate is the mean of v v^T - H P H^T, clipped between the
datasheet and a hundred times it; a filter told GNSS is 3x better than it is turns over-confident,
and with IAE it learns the real noise and its NEES comes back near its expected value."""

import numpy as np
import pytest

from experiments.harness import nees_series_of_filters
from vehicle.estimators.adaptive import CEILING, FLOOR, InnovationWindow

pytestmark = pytest.mark.monte_carlo


RUNS, DURATION_S, FROM_S = 40, 60.0, 30  # scored once the early over-confidence has worn off
TRUE_FACTOR = 3.0
NOMINAL_VAR = 1.5**2


def test_the_window_estimates_the_noise_and_stays_within_the_datasheet_bounds():
    rng, nominal = np.random.default_rng(1), np.eye(2)
    window = InnovationWindow(2000)
    spread = np.diag([0.5, 0.2])
    for _ in range(2000):
        window.add(rng.multivariate_normal(np.zeros(2), spread + np.diag([4.0, 9.0])), spread)
    assert np.allclose(window.covariance(nominal), np.diag([4.0, 9.0]), rtol=0.1, atol=0.3)
    small = InnovationWindow(5)  # usable after 5
    assert small.covariance(nominal) is nominal  # not usable yet: the datasheet
    for _ in range(5):
        small.add(np.zeros(2), np.eye(2))  # innovations smaller than predicted: R_hat < 0
    assert FLOOR == 1.0 and np.allclose(small.covariance(nominal), nominal)  # never below the datasheet
    quieter = InnovationWindow(500)  # a sensor that seems twice as good as its datasheet: the CI bound's slack
    for _ in range(500):
        quieter.add(rng.multivariate_normal(np.zeros(2), 0.5 * np.eye(2)), np.zeros((2, 2)))
    assert np.allclose(quieter.covariance(nominal), nominal)
    for _ in range(5):
        small.add(np.array([1e3, 0.0]), np.zeros((2, 2)))
    assert np.isclose(np.linalg.eigvalsh(small.covariance(nominal)).max(), CEILING)


def _monte_carlo() -> tuple[np.ndarray, np.ndarray, list]:
    """NEES from FROM_S of the filter told the datasheet and of the one with IAE (RUNS, steps) each,
    both on each run's world, and the IAE filters at the end."""
    told, adapted, filters = [], [], []
    for seed in range(RUNS):
        runs = nees_series_of_filters(
            seed,
            [{"adaptive_window": 0}, {"adaptive_window": 40}],
            duration_s=DURATION_S,
            trajectory=("circle", "figure8", "waypoints")[seed % 3],
            world={"sensor_truth": {"gnss_sigma_factor": TRUE_FACTOR}},
            estimators_out=filters,
        )
        told.append(runs[0][0][FROM_S:])
        adapted.append(runs[1][0][FROM_S:])
    return np.array(told), np.array(adapted), filters[1::2]


def _anees_interval(nees: np.ndarray) -> tuple[float, float]:
    """95% interval of the ANEES from the spread of the per-run means (runs are independent, samples
    inside a run are not), as in test_estimator_consistency."""
    per_run = nees.mean(axis=1)
    half = 1.96 * per_run.std(ddof=1) / np.sqrt(len(per_run))
    return per_run.mean() - half, per_run.mean() + half


def test_iae_learns_the_real_gnss_noise_and_brings_the_nees_back_near_its_expected_value():
    """Told 1.5 m, the receiver's noise is 4.5 m: without IAE the filter is grossly over-confident
    (measured ANEES interval [22, 36]); with IAE it learns about 9x the datasheet's variance (8.9x)
    and its ANEES comes back to [3.1, 4.4]: not inside the band around 3, the rest is the process
    model's own over-confidence between fixes that weigh less now (dead reckoning alone: ANEES 3.35
    in test_cooperative_stages). Scored from 30 s: the early part, when it trusted the datasheet,
    takes a while to wear off."""
    told, adapted, filters = _monte_carlo()
    assert _anees_interval(told)[0] > 10.0, _anees_interval(told)
    lo, hi = _anees_interval(adapted)
    assert 2.0 < lo and hi < 5.0, (lo, hi)
    learned = np.array([np.diag(f.state.iae.estimates()["gnss"]) for f in filters]) / NOMINAL_VAR
    assert 0.7 * TRUE_FACTOR**2 < np.median(learned) < 1.3 * TRUE_FACTOR**2, np.median(learned)
