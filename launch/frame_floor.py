"""The frame floor of a replay's calibration (``sensors.frame_sigma_m``): how far, per axis, the
position a robot's sightings give may lie from where its truth (Vicon) has it, however many
sightings there are.

Sightings place a robot against the landmarks as its camera sees them; Vicon places it by the
markers on its body. The two differ by what no sighting can see: where a barcode sits on its
landmark against the landmark's surveyed point, where the camera sits against Vicon's centre of the
robot. A filter that averages many sightings takes that difference for gone: on data set 6, with
its cameras' readouts calibrated, a known-map robot claims 0.3-1 cm across its track while it is
3 cm off for a minute on end. The vehicle adds the floor to the position covariance it publishes,
not to its filter's own, which only the sightings correct.

The fit: the known-map filters, with the datasheet just calibrated, replayed over the calibration
interval in this process (launch.in_process); the floor is the sigma that, added to each position
variance, brings the position NEES (2 dof), pooled over the robots and the interval, to 2; none when
it is 2 or less without one.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from bus import statistics
from bus.config import SwarmConfig
from launch.in_process import replay_in_memory
from vehicle.estimators import get_estimator

SCORE_EVERY_US = 100_000
MAX_FLOOR_M = 10.0


def floor_sigma(errors: np.ndarray, covariances: np.ndarray, dof_mean: float = 2.0) -> float:
    """The sigma s (m) >= 0 with mean_k e_k' (P_k + s^2 I)^-1 e_k = ``dof_mean`` over position
    errors (k, 2) m and their covariances (k, 2, 2) m^2; 0 when the mean is at most that without."""

    def excess(sigma: float) -> float:
        widened = covariances + sigma**2 * np.eye(2)
        return float(np.mean(np.einsum("ki,kij,kj->k", errors, np.linalg.inv(widened), errors))) - dof_mean

    if len(errors) == 0 or excess(0.0) <= 0:
        return 0.0
    return float(brentq(excess, 0.0, MAX_FLOOR_M, xtol=1e-5))


def fit_frame_sigma(config: SwarmConfig | None, data) -> float:
    """The floor (module docstring) fitted on the replay ``config`` (known-map, inside the calibration
    interval, ``replay.fitting``) of ``data``; 0 for no config."""
    if config is None:
        return 0.0
    vehicle_config = config.for_vehicle()
    estimators = {vid: get_estimator(vehicle_config, vid) for vid in range(1, config.world.vehicles + 1)}
    errors, covariances = [], []

    def keep(estimator, truth_pose: np.ndarray) -> tuple[float, float]:
        error = statistics.pose_error(estimator.state.x[:3], truth_pose)
        errors.append(error[:2])
        covariances.append(estimator.state.P[:2, :2].copy())
        return 0.0, 0.0

    replay_in_memory(config, data, every_us=SCORE_EVERY_US, estimators=estimators, scorer=keep)
    return floor_sigma(np.array(errors).reshape(-1, 2), np.array(covariances).reshape(-1, 2, 2))
