"""The vehicle filters (EKF and UKF) are consistent: NEES inside chi-square bounds over seeded Monte
Carlo runs, and the checks are two-sided (an over- and an under-confident filter both fail them)."""

import numpy as np
import pytest
from scipy.stats import chi2

from bus.config import SensorSpec
from experiments.harness import nees_series_of_filters, pose_nees_series

pytestmark = pytest.mark.monte_carlo


RUNS = 50
DOF = 3
KINDS = ("circle", "figure8", "waypoints")


def _monte_carlo(estimator_spec=None, kind: str = "ekf") -> np.ndarray:
    """(RUNS, steps) NEES, one seeded run each, trajectories cycling through every kind."""
    return np.array(
        [
            pose_nees_series(
                seed, duration_s=20.0, trajectory=KINDS[seed % 3], estimator_spec=estimator_spec, kind=kind
            )[0]
            for seed in range(RUNS)
        ]
    )


def _fraction_inside_bounds(nees: np.ndarray) -> float:
    """Share of time steps whose run-averaged NEES lies in the two-sided 95% bounds (Bar-Shalom):
    at one time the runs are independent, so the average of RUNS NEES is chi2(DOF * RUNS) / RUNS."""
    lo, hi = chi2.ppf([0.025, 0.975], DOF * RUNS) / RUNS
    mean = nees.mean(axis=0)
    return float(np.mean((mean >= lo) & (mean <= hi)))


def _anees_interval(nees: np.ndarray) -> tuple[float, float]:
    """95% interval of the grand ANEES from the spread of the per-run means (runs are independent;
    the samples inside one run are not, so their count cannot set the width)."""
    per_run = nees.mean(axis=1)
    half = 1.96 * per_run.std(ddof=1) / np.sqrt(len(per_run))
    return per_run.mean() - half, per_run.mean() + half


@pytest.mark.parametrize("kind", ["ekf", "ukf"])
def test_nees_stays_inside_95_percent_bounds(kind):
    nees = _monte_carlo(kind=kind)
    assert nees.shape == (RUNS, 21)  # t = 0, 1, ..., 20 s
    assert _fraction_inside_bounds(nees) >= 0.9
    lo, hi = _anees_interval(nees)
    assert lo <= DOF <= hi and hi - lo < 1.0  # consistent, and measured tightly enough to mean it


def test_the_check_catches_an_overconfident_and_an_underconfident_filter():
    """Same harness, filter told its gyro is 20x better, or 20x worse, than it is."""
    optimistic = SensorSpec(gyro_sigma_radps=0.0005, gyro_bias_sigma_radps=0.0005, gyro_bias_walk_radps_rtsec=0.0)
    pessimistic = SensorSpec(gyro_sigma_radps=0.2, gyro_bias_walk_radps_rtsec=0.01)
    runs = [
        nees_series_of_filters(
            seed,
            [{"estimator_spec": optimistic}, {"estimator_spec": pessimistic}],
            duration_s=20.0,
            trajectory=KINDS[seed % 3],
        )
        for seed in range(RUNS)
    ]
    for i, side in enumerate(("over", "under")):
        nees = np.array([run[i][0] for run in runs])
        lo, hi = _anees_interval(nees)
        assert _fraction_inside_bounds(nees) < 0.5, side
        assert (lo > DOF) if side == "over" else (hi < DOF), side
