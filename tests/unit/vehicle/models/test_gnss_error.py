"""The GNSS error states (vehicle.models.gnss_error): the model's algebra, the datasheet's checks, and the
point of them: a filter fusing fixes whose error wanders over a minute stays consistent only when it
estimates that error (two-sided: without the states the same harness finds it over-confident)."""

import numpy as np
import pytest
from pydantic import ValidationError

from bus.config import SensorSpec
from experiments.harness import nees_series_of_filters, pose_nees_series
from vehicle.models.gnss_error import GnssErrorModel, aligned_covariance, augment_motion, observation

pytestmark = pytest.mark.monte_carlo


RUNS = 30
KINDS = ("circle", "figure8", "waypoints")
GAUSS_MARKOV_WORLD = {"sensor_truth": {"gnss_sigma_factor": 0.8, "gnss_walk_sigma_m": 0.9, "gnss_walk_tau_s": 60.0}}


def test_the_model_decays_to_its_stationary_spread_and_splits_the_reported_noise():
    model = GnssErrorModel.from_spec(SensorSpec(gnss_sigma_m=1.5, gnss_correlated_sigma_m=0.9, gnss_correlation_s=60.0))
    phi, q = model.transition(60.0)
    assert phi == pytest.approx(np.exp(-1.0)) and q == pytest.approx(0.81 * (1.0 - np.exp(-2.0)))
    assert phi**2 * 0.81 + q == pytest.approx(0.81)  # stationary: the variance stays sigma^2
    np.testing.assert_allclose(model.white(np.eye(2) * 2.25), np.eye(2) * 1.44)  # 1.5^2 = 1.2^2 + 0.9^2
    np.testing.assert_allclose(model.white(np.eye(2) * 9.0), np.eye(2) * 5.76)  # a degraded fix keeps the share
    F, Q = augment_motion(np.eye(4) * 2.0, np.eye(4), model, 60.0)
    assert F.shape == Q.shape == (6, 6) and F[4, 4] == F[5, 5] == pytest.approx(phi) and F[4, :4].sum() == 0.0
    H = observation(6)
    np.testing.assert_array_equal(H @ np.arange(6.0), [0.0 + 4.0, 1.0 + 5.0])
    P = aligned_covariance(np.eye(3) * 0.1, model)
    assert np.all(np.linalg.eigvalsh(P[np.ix_([0, 1, 4, 5], [0, 1, 4, 5])]) > 0)
    assert P[0, 4] == pytest.approx(-0.81)  # position error = e + white average, error state error = -e
    assert GnssErrorModel.from_spec(SensorSpec()) is None  # the default datasheet calls GNSS white


def test_the_datasheet_refuses_a_correlated_part_larger_than_the_total():
    with pytest.raises(ValidationError, match="gnss_correlated_sigma_m .* must be below gnss_sigma_m"):
        SensorSpec(gnss_sigma_m=1.0, gnss_correlated_sigma_m=1.0)


def _per_run_anees(specs: list[SensorSpec]) -> list[np.ndarray]:
    """Each run's ANEES (RUNS,) of an EKF told each of ``specs``, all on each run's world."""
    runs = [
        nees_series_of_filters(
            seed,
            [{"estimator_spec": spec} for spec in specs],
            duration_s=60.0,
            trajectory=KINDS[seed % 3],
            world=GAUSS_MARKOV_WORLD,
        )
        for seed in range(RUNS)
    ]
    return [np.array([run[i][0].mean() for run in runs]) for i in range(len(specs))]


def test_estimating_the_wandering_gnss_error_keeps_the_filter_consistent():
    """The world's fixes: 1.2 m white + 0.9 m Gauss-Markov over 60 s (1.5 m in all, the datasheet's
    total). Told only the total, the filter averages correlated fixes as if independent (ANEES measured
    ~54); told the datasheet's rounded split (1 m over a minute), its ANEES interval holds 3 (3.0 +- 0.6
    at 50 runs)."""
    split = SensorSpec(gnss_correlated_sigma_m=1.0, gnss_correlation_s=60.0)
    told_white, told_split = _per_run_anees([SensorSpec(), split])
    half = 1.96 * told_split.std(ddof=1) / np.sqrt(RUNS)
    assert told_split.mean() - half <= 3.0 <= told_split.mean() + half and half < 1.0, (told_split.mean(), half)
    assert told_white.mean() - 1.96 * told_white.std(ddof=1) / np.sqrt(RUNS) > 10.0, told_white.mean()


def test_the_ukf_carries_the_same_states():
    """Same world, UKF: its ANEES interval holds 3 as well (fewer runs: it is slower)."""
    runs = np.array(
        [
            pose_nees_series(
                seed,
                duration_s=40.0,
                trajectory=KINDS[seed % 3],
                world=GAUSS_MARKOV_WORLD,
                estimator_spec=SensorSpec(gnss_correlated_sigma_m=1.0),
                kind="ukf",
            )[0].mean()
            for seed in range(12)
        ]
    )
    half = 1.96 * runs.std(ddof=1) / np.sqrt(len(runs))
    assert runs.mean() - half <= 3.0 <= runs.mean() + half, (runs.mean(), half)
