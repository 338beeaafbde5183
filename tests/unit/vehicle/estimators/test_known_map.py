"""``known-map``: consistent where its datasheet is right (NEES of seeded Monte Carlo runs inside the
chi-square band, both sides), robust where the data is not (unknown ids and misreadings are not
fused; a robot whose estimate is far off re-localizes against the map instead of staying lost)."""

import dataclasses

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
from vehicle.estimators import get_estimator, known_map

pytestmark = pytest.mark.monte_carlo


RUNS, SAMPLES_FROM_S = 12, 20


def test_nees_is_inside_the_chi_square_band_over_seeded_runs():
    nees = []
    for seed in range(RUNS):
        data = synthetic(np.random.default_rng(100 + seed), robots=1, duration_s=101.0)
        rows = replay_in_memory(replay_config("known-map", seed), data, every_us=10_000_000)[1]
        nees += rows[rows[:, 0] >= SAMPLES_FROM_S * 1e6, 2].tolist()
    low, high = chi2.ppf([0.025, 0.975], 3 * len(nees)) / len(nees)
    assert low <= np.mean(nees) <= high, (np.mean(nees), low, high)


def _persisting_errors_nees(sensors: dict) -> tuple[float, float, float]:
    """ANEES and its 95 % band over seeded runs of :func:`with_persisting_errors` for a filter told
    ``sensors``."""
    nees = []
    for seed in range(RUNS):
        data = with_persisting_errors(np.random.default_rng(200 + seed))
        config = replay_config("known-map", seed, sensors, sighting_sigmas=[PERSISTING_SIGHTING_SIGMAS])
        rows = replay_in_memory(config, data, every_us=10_000_000)[1]
        nees += rows[rows[:, 0] >= SAMPLES_FROM_S * 1e6, 2].tolist()
    low, high = chi2.ppf([0.025, 0.975], 3 * len(nees)) / len(nees)
    return float(np.mean(nees)), float(low), float(high)


def test_persisting_errors_modelled_keep_nees_inside_the_band():
    anees, low, high = _persisting_errors_nees(PERSISTING_SENSORS)
    assert low <= anees <= high, (anees, low, high)


def test_persisting_errors_taken_as_white_make_the_filter_overconfident():
    anees, _, high = _persisting_errors_nees({})  # the control: the same data, nothing modelled
    assert anees > 2 * high, anees
    without_bearing = {key: value for key, value in PERSISTING_SENSORS.items() if not key.startswith("bearing")}
    anees, _, high = _persisting_errors_nees(without_bearing)  # the bearing's persisting part taken as white
    assert anees > high, anees


def _range_scale_nees(sensors: dict) -> tuple[float, float, float]:
    """ANEES and its 95 % band over seeded runs of robots whose cameras read every range 6 % long or
    5 % short, for a filter told ``sensors`` (the nominal datasheet otherwise)."""
    nees = []
    for seed in range(RUNS):
        data = synthetic(
            np.random.default_rng(300 + seed),
            robots=1,
            duration_s=101.0,
            sighting_rate_hz=6.0,
            range_scale=(0.06, -0.05)[seed % 2],
        )
        rows = replay_in_memory(replay_config("known-map", seed, sensors), data, every_us=10_000_000)[1]
        nees += rows[rows[:, 0] >= SAMPLES_FROM_S * 1e6, 2].tolist()
    low, high = chi2.ppf([0.025, 0.975], 3 * len(nees)) / len(nees)
    return float(np.mean(nees)), float(low), float(high)


def test_a_camera_range_scale_that_is_off_is_estimated_and_nees_stays_inside_the_band():
    anees, low, high = _range_scale_nees({"range_scale_prior_sigma": 0.05})
    assert low <= anees <= high, (anees, low, high)
    anees, _, high = _range_scale_nees({})  # the control: the same data, the scale taken as exact
    assert anees > high, anees


class _WrongPrior:
    """A known-map filter that takes the launch prior 1.5 m and 0.4 rad off while believing it within
    5 cm and 1 degree (everything but ``handle`` is the filter's)."""

    def __init__(self, inner) -> None:
        self.inner = inner

    def __getattr__(self, name: str):
        return getattr(self.inner, name)

    def handle(self, msg):
        if isinstance(msg, m.PosePrior):
            msg = dataclasses.replace(msg, pose=msg.pose + [1.5, -0.5, 0.4])
        self.inner.handle(msg)


def _lost_start(config, vehicle_id: int = 1) -> object:
    return _WrongPrior(known_map.from_config(config.for_vehicle(), vehicle_id))


@pytest.mark.parametrize("relocalize", [True, False])
def test_a_lost_robot_relocalizes_against_the_map(monkeypatch, relocalize):
    if not relocalize:
        monkeypatch.setattr(known_map, "LOST_AFTER", 10**9)
    data = synthetic(np.random.default_rng(7), robots=1, duration_s=101.0)
    config = replay_config("known-map", 0)
    estimator = _lost_start(config)
    rows = replay_in_memory(config, data, estimators={1: estimator})[1]
    final_error = rows[-10:, 1].max()
    if relocalize:
        assert final_error < 0.3 and estimator.counters.resets >= 1
        assert any("lost track" in n.text for n in estimator.notices.take())
    else:
        assert final_error > 1.0  # the control: without re-localizing, the gate keeps the map out


def test_unknown_landmarks_and_misreadings_are_not_fused():
    config = replay_config("known-map", 0)
    estimator = get_estimator(config.for_vehicle(), 1)
    estimator.handle(m.PosePrior(1, 0, 0, np.zeros(3), np.diag([0.01, 0.01, 0.001])))
    x0, P0 = estimator.x.copy(), estimator.P.copy()
    cov = np.diag([0.01, 0.0004])
    estimator.handle(m.LandmarkSighting(1, 1000, 0, 99, 3.0, 0.1, cov))  # not on the map
    assert estimator.state.landmarks.unknown_landmarks == 1 and np.array_equal(estimator.x, x0)
    lx, ly = LANDMARKS[6, 1:3]  # landmark 12 at (4, 0): truly 4 m ahead; read as 7 m (a misreading)
    estimator.handle(m.LandmarkSighting(1, 2000, 1, 12, np.hypot(lx, ly) + 3.0, 0.0, cov))
    assert estimator.state.landmarks.rejected == 1 and np.allclose(estimator.x[:2], x0[:2], atol=1e-3)
    estimator.handle(m.LandmarkSighting(1, 3000, 2, 12, np.hypot(lx, ly) + 0.05, 0.0, cov))
    assert estimator.state.landmarks.fused == 1 and np.all(np.diagonal(estimator.P)[:2] < np.diagonal(P0)[:2])


def test_the_landmark_nis_a_vehicle_reports_is_that_of_a_consistent_filter():
    """Where the datasheet is right, the NIS the filter reports for its landmark sightings (the
    VehicleStatus ``nis`` book) has mean 2, 5 % of it above chi-square(2)'s 95 % point and 5 % below
    its 5 % point."""
    from bus.consistency import nis_summary

    counts, means, above, below = [], [], [], []
    for seed in range(8):
        data = synthetic(np.random.default_rng(700 + seed), robots=1, duration_s=101.0)
        config = replay_config("known-map", seed)
        estimator = get_estimator(config.for_vehicle(), 1)
        replay_in_memory(config, data, estimators={1: estimator})
        landmark = nis_summary(estimator.counters.nis.values)["landmark"]
        counts.append(landmark["count"])
        means.append(landmark["mean"])
        above.append(landmark["share_above_95"])
        below.append(landmark["share_below_05"])
    weights = np.array(counts) / sum(counts)
    assert sum(counts) > 1200
    assert 1.8 <= float(weights @ means) <= 2.2, means
    assert 0.03 <= float(weights @ above) <= 0.07, above
    assert 0.03 <= float(weights @ below) <= 0.07, below
