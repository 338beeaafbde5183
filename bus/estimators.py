"""The estimators a vehicle can run, by the name a configuration gives them (``vehicle.estimator``):
the one registry. Each entry names the module that builds the estimator (its ``from_config(config,
vehicle_id, reject=...)``, resolved by ``vehicle.estimators.get_estimator``) and says in a line what it
is, and what it needs of the configuration (``NEEDS``: a camera, the surveyed map), which the
configuration's validation checks for every estimator alike; the configuration's allowed names and
the generated config reference come from here. Adding an estimator is one new module under
``vehicle/estimators/`` and one line here."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

NEEDS = {
    "camera": "a camera: set sensors.camera_rate_hz (e.g. 10), or replay a data set's sightings",
    "map": "the surveyed map: vehicle.landmarks",
    "camera3d": "a UAV's 3-D camera: set sensors.camera3d.rate_hz (e.g. 10)",
}


@dataclass(frozen=True)
class EstimatorEntry:
    module: str  # the module whose from_config builds it
    summary: str  # one line for the config reference
    needs: frozenset[str] = frozenset()  # of NEEDS
    estimates_height: bool = False  # publishes its height (ODOMETRY z): the ground station scores it, the views plot it


ESTIMATORS: dict[str, EstimatorEntry] = {
    "ekf": EstimatorEntry(
        "vehicle.estimators.ekf",
        "EKF over [x, y, theta, gyro bias]: odometry and gyro, GNSS behind its health monitor, neighbours by CI",
    ),
    "ukf": EstimatorEntry(
        "vehicle.estimators.ukf", "the same filter with the unscented transform for the motion and neighbours' fixes"
    ),
    "known-map": EstimatorEntry(
        "vehicle.estimators.known_map",
        "the EKF with camera sightings of surveyed landmarks (vehicle.landmarks) and their persisting errors",
        frozenset({"map"}),
    ),
    "ekf-slam": EstimatorEntry(
        "vehicle.estimators.ekf_slam",
        "vision EKF-SLAM: landmarks from camera frames (or a replay's sightings) mapped as it flies",
        frozenset({"camera"}),
    ),
    "ar-ekf-slam": EstimatorEntry(
        "vehicle.estimators.ar_ekf_slam",
        "EKF-SLAM keeping only the landmarks within an adaptive range in its state (AR-EKF-SLAM paper)",
        frozenset({"camera"}),
    ),
    "ar-ekf-slam-3d": EstimatorEntry(
        "vehicle.estimators.ar_ekf_slam_3d",
        "the AR-EKF-SLAM paper's 3-D system: [p, v] + 3 per landmark from a UAV's 3-D camera and GNSS",
        frozenset({"camera3d"}),
        estimates_height=True,
    ),
}

EstimatorName = Literal[tuple(ESTIMATORS)]  # type: ignore[valid-type]
