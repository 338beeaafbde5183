"""``ekf-slam`` on a replayed data set's identified landmark sightings: it maps the landmarks where
they are (within their own 3-sigma) and localizes far better than dead reckoning on the same data."""

import numpy as np
import pytest
from scipy.stats import chi2

from bus import messages as m
from experiments.harness import replay_in_memory
from tests.synthetic_mrclam import (
    LANDMARKS,
    PERSISTING_SENSORS,
    PERSISTING_SIGHTING_SIGMAS,
    replay_config,
    synthetic,
    with_persisting_errors,
)
from vehicle.estimators import get_estimator, persisting_errors

pytestmark = pytest.mark.monte_carlo


def test_slam_maps_identified_landmarks_and_beats_dead_reckoning():
    data = synthetic(np.random.default_rng(11), robots=1, duration_s=101.0)
    config = replay_config("ekf-slam", 3)
    slam = get_estimator(config.for_vehicle(), 1)
    slam_rows = replay_in_memory(config, data, estimators={1: slam})[1]
    dead_rows = replay_in_memory(replay_config("ekf", 3), data)[1]
    assert np.sqrt(np.mean(slam_rows[:, 1] ** 2)) < 0.5 * np.sqrt(np.mean(dead_rows[:, 1] ** 2))
    positions, covariances = slam.landmark_map()
    assert 3 <= len(positions) <= len(LANDMARKS)
    truth = {int(i): LANDMARKS[LANDMARKS[:, 0] == i, 1:3][0] for i in slam.state.landmarks.index_of}
    for ident, j in slam.state.landmarks.index_of.items():
        d = positions[j] - truth[ident]
        assert d @ np.linalg.solve(covariances[j], d) < chi2.ppf(0.9973, 2), ident


RUNS, SAMPLES_FROM_S = 20, 20


def _persisting_errors_nees(sensors: dict) -> tuple[np.ndarray, float, float]:
    """ANEES of ekf-slam at each 10 s checkpoint from SAMPLES_FROM_S over seeded runs of
    :func:`with_persisting_errors` for a filter told ``sensors``, and the 99 % band of one
    checkpoint. Checkpoint by checkpoint, across runs: a SLAM filter's error keeps its launch prior's
    share for the whole run (where the map sits
    is unobservable), so the checkpoints of one run are not independent samples."""
    nees = []
    for seed in range(RUNS):
        data = with_persisting_errors(np.random.default_rng(200 + seed))
        config = replay_config("ekf-slam", seed, sensors, sighting_sigmas=[PERSISTING_SIGHTING_SIGMAS])
        rows = replay_in_memory(config, data, every_us=10_000_000)[1]
        nees.append(rows[rows[:, 0] >= SAMPLES_FROM_S * 1e6, 2])
    low, high = chi2.ppf([0.005, 0.995], 3 * RUNS) / RUNS
    return np.mean(nees, axis=0), float(low), float(high)


def test_persisting_errors_modelled_keep_slam_nees_inside_the_band():
    anees, low, high = _persisting_errors_nees(PERSISTING_SENSORS)
    assert np.all((low <= anees) & (anees <= high)), (anees, low, high)


def test_persisting_errors_taken_as_white_make_slam_overconfident():
    anees, _, high = _persisting_errors_nees({})  # the control: the same data, nothing modelled
    assert np.mean(anees) > 2 * high, anees


def test_error_slots_go_to_the_landmarks_seen_last(monkeypatch):
    """With three slots ([s, b] each), a fourth landmark takes the slot of the one seen longest ago,
    reset to 0 with the stationary spreads and uncorrelated (that landmark's old errors
    marginalized); a landmark seen again keeps its slot."""
    monkeypatch.setattr(persisting_errors, "ERROR_SLOTS", 3)
    sensors = {**PERSISTING_SENSORS, "bearing_correlated_fraction": 0.5, "bearing_correlation_s": 5.0}
    slam = get_estimator(replay_config("ekf-slam", 3, sensors).for_vehicle(), 1)
    slam.handle(m.PosePrior(1, 0, 0, np.zeros(3), np.diag([0.01, 0.01, 0.001])))
    R = np.diag([0.04, 0.0004])

    def sight(t_s: float, ident: int) -> None:
        slam.handle(m.LandmarkSighting(1, int(t_s * 1e6), 0, ident, 3.0, 0.1 * ident, R))

    for t_s, ident in ((0.1, 6), (0.2, 7), (0.3, 8), (0.4, 6)):  # 6 again: most recent of the three
        sight(t_s, ident)
    slots = {ident: slot for (_, ident), slot in slam.state.errors.slot_of.items()}
    assert sorted(slots.values()) == list(range(slam.errors.head_dim - 6, slam.errors.head_dim, 2))
    sight(0.5, 9)
    now = {ident: slot for (_, ident), slot in slam.state.errors.slot_of.items()}
    assert now == {9: slots[7], 6: slots[6], 8: slots[8]}
    assert slam.counters.landmarks == 4
    slot = slam.errors.index_of(
        slam.state, slam.store, ("landmark", 7), 600_000, R[1, 1]
    )  # back: the slot of the one seen longest ago (8)
    assert slot == slots[8] and ("landmark", 8) not in slam.state.errors.slot_of
    states = [slot, slot + 1]
    assert not np.any(slam.x[states])
    expected = [PERSISTING_SENSORS["range_correlated_sigma_per_m"] ** 2, 0.5 * R[1, 1]]
    np.testing.assert_array_equal(np.diagonal(slam.P)[states], expected)
    assert not np.any(np.delete(slam.P[states], states, axis=1))
