"""``ekf-slam``: vision EKF-SLAM (vision EKF-SLAM paper): the ``ekf``'s pose [x, y, theta,
gyro_bias], the persisting-error states (wheel scales, the camera's error slots:
vehicle.estimators.persisting_errors, ``SlottedErrors``: ``head_dim`` states), then the map
[l1x, l1y, l2x, l2y, ...] (m), kept with the camera's front end by ``vehicle.estimators.vision_map``
(what each frame or a replay's sighting does). Odometry, IMU, GNSS (when there is any, taken as
white: the map's camera fixes anchor the position) and cooperative fixes act as in ``ekf``; every
change touches x and P in place (``InPlaceStore``): the prediction moves the head and its
cross-covariances, each update is O(n) for its gain and O(n^2) flops with no n x n temporary.
Fusion-horizon snapshots copy (x, P) only where the horizon asks for one; the divergence fallback is
refreshed once per second (``MapCheck``).
"""

from __future__ import annotations

import numpy as np

from bus.config import SensorSpec, VehicleProcessConfig
from vehicle.estimators.divergence import MapCheck
from vehicle.estimators.filter import Filter
from vehicle.estimators.persisting_errors import SlottedErrors
from vehicle.estimators.settings import shared_arguments
from vehicle.estimators.state import FilterState
from vehicle.estimators.stores import InPlaceStore
from vehicle.estimators.updates import Linearized
from vehicle.estimators.vision_map import MapPolicy, Reject, VisionSlamMap
from vehicle.models.cooperative import CooperativeRule
from vehicle.models.gnss import WhiteGnss
from vehicle.models.motion import POSE_DIM, UnicycleMotion
from vehicle.trust.neighbours import MonitorSpec

MAX_LANDMARKS = 2000  # the map stops growing here (update cost is O(n^2))


class FullMap:
    """``ekf-slam``'s map policy: every landmark stays in the state, up to ``MAX_LANDMARKS``."""

    capacity = MAX_LANDMARKS

    def start(self) -> None:
        return None

    def before_frame(self, s: FilterState, the_map: VisionSlamMap) -> None:
        """Nothing to manage."""

    def reenter(self, s: FilterState, the_map, found, z, R, matched: set[int], half_extent_m: float) -> set[int]:
        """No landmark ever leaves: nothing re-enters."""
        return set()

    def occupied(self, s: FilterState) -> np.ndarray | None:
        """Where landmarks outside the state lie (new ones keep away from them): none."""
        return None

    def before_sighting(self, s: FilterState, the_map: VisionSlamMap, stamp_us: int) -> None:
        """Nothing to manage."""

    def take_retired(self, s: FilterState, ident: int) -> None:
        """An identified landmark that left the state: none ever leaves."""
        return None

    def reentered(self, s: FilterState, k: int, retired: tuple[np.ndarray, np.ndarray]) -> None:
        """Nothing re-enters."""


def build(
    *,
    vehicle_id: int,
    spec: SensorSpec,
    gate_probability: float,
    detector: str = "sift",
    reject: Reject | None = None,
    first_estimates: bool = True,
    cooperative: CooperativeRule = CooperativeRule(),
    adaptive_window: int = 0,
    front_end_results: dict | None = None,
    monitor: MonitorSpec | None = MonitorSpec(),
    policy: MapPolicy | None = None,
    association: str = "descriptor",
) -> Filter:
    """The EKF-SLAM filter of vehicle ``vehicle_id`` (module docstring); ``reject(reason, where,
    detail)`` counts the camera frames it refuses; ``first_estimates`` False: Jacobians at the
    current estimates (the paper's EKF); ``policy``: which landmarks the state keeps (``FullMap``
    by default)."""
    wheel_scales = bool(spec.odom_scale_prior_sigma)
    errors = SlottedErrors(spec, first_index=POSE_DIM + (2 if wheel_scales else 0))
    the_map = VisionSlamMap(
        head_dim=errors.head_dim,
        vehicle_id=vehicle_id,
        keypoint_sigma_px=spec.keypoint_sigma_px,
        detector=detector,
        reject=reject,
        first_estimates=first_estimates,
        front_end_results=front_end_results,
        policy=FullMap() if policy is None else policy,
        association=association,
    )
    return Filter(
        name="ekf-slam",
        vehicle_id=vehicle_id,
        spec=spec,
        gate_probability=gate_probability,
        gnss=WhiteGnss(),
        motion=UnicycleMotion(wheel_scales=wheel_scales, first_estimates=first_estimates),
        update=Linearized(),
        store=InPlaceStore(),
        divergence=MapCheck(),
        errors=errors,
        sightings=the_map,
        cooperative=cooperative,
        adaptive_window=adaptive_window,
        monitor=monitor,
    )


def config_arguments(config: VehicleProcessConfig, vehicle_id: int, reject: Reject | None) -> dict:
    """:func:`build`'s arguments from a vehicle's configuration (also ``ar_ekf_slam``'s)."""
    vc = config.vehicle
    return {
        **shared_arguments(config, vehicle_id),
        "detector": vc.features,
        "reject": reject,
        "association": vc.association,
    }


def from_config(config: VehicleProcessConfig, vehicle_id: int, *, reject: Reject | None = None) -> Filter:
    """:func:`build` from a vehicle's configuration (its keypoint detector is ``vehicle.features``)."""
    return build(**config_arguments(config, vehicle_id, reject))
