"""``ekf-slam`` on a replayed data set's identified landmark sightings: it maps the landmarks where
they are (within their own 3-sigma) and localizes far better than dead reckoning on the same data."""

import numpy as np
from scipy.stats import chi2

from bus.config import build_config
from tests.offline import replay_in_memory
from tests.synthetic_mrclam import LANDMARKS, synthetic
from vehicle.estimators import get_estimator


def _config(estimator: str) -> object:
    return build_config({
        "world": {"vehicles": 1, "seed": 3}, "clock": {"duration_s": 80.0, "tick_s": 0.02},
        "sensors": {"odom_speed_sigma_mps": 0.05, "odom_yaw_rate_sigma_radps": 0.1, "range_sigma_m": 0.1,
                    "bearing_sigma_rad": 0.02, "prior_sigma_m": 0.05, "prior_heading_sigma_rad": 0.02},
        "vehicle": {"estimator": estimator, "cooperative": False},
        "replay": {"dataset": "synthetic", "robots": [1], "start_s": 20.0, "calibration_s": [0, 20], "odom_lag_s": 0.2}})


def test_slam_maps_identified_landmarks_and_beats_dead_reckoning():
    data = synthetic(np.random.default_rng(11), robots=1, duration_s=101.0)
    config = _config("ekf-slam")
    slam = get_estimator(config.for_vehicle(), 1)
    slam_rows = replay_in_memory(config, data, estimators={1: slam})[1]
    dead_rows = replay_in_memory(_config("ekf"), data)[1]
    assert np.sqrt(np.mean(slam_rows[:, 1] ** 2)) < 0.5 * np.sqrt(np.mean(dead_rows[:, 1] ** 2))
    positions, covariances = slam.landmark_map()
    assert 3 <= len(positions) <= len(LANDMARKS)
    truth = {int(i): LANDMARKS[LANDMARKS[:, 0] == i, 1:3][0] for i in slam._slot}
    for ident, j in slam._slot.items():
        d = positions[j] - truth[ident]
        assert d @ np.linalg.solve(covariances[j], d) < chi2.ppf(0.9973, 2), ident
