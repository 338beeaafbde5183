"""``known-map``: the ``ekf`` localizing against a surveyed map of landmarks (``vehicle.landmarks``,
id -> position) from camera range-bearing sightings of them.

Each sighting is one EKF update with the range-bearing model of the vision EKF-SLAM paper,
h = [sqrt(dx^2 + dy^2), atan2(dy, dx) - theta] with (dx, dy) = landmark - position (the landmark a
known constant, so only the pose rows of H), behind a chi-square gate: a misread barcode or an
occluded target fails it and is counted, not fused. Odometry, GNSS and cooperative fixes act as in
``ekf``. The sensor errors that persist (wheel scales, the camera's range scale, each landmark's
correlated range and bearing errors) are states, added and forgotten as landmarks come and go
(vehicle.estimators.persisting_errors, ``GrowingErrors``): a camera that reads a landmark 3 % long
reads it 3 % long for seconds, and fusing five such sightings a second as independent would make
the filter sure of a biased pose.

Losing track and finding it again: when ``LOST_AFTER`` sightings in a row of at least two different
landmarks all fail the gate, the pose is no longer where the filter believes; its covariance is
widened by ``RELOCALIZE_SIGMA`` (position and heading, cross terms dropped) so the next sightings
pass the gate and pull it back onto the map, and a notice says so.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from bus.config import SensorSpec, VehicleProcessConfig
from vehicle.estimators.divergence import FullCheck
from vehicle.estimators.filter import Filter
from vehicle.estimators.parts import Fusing, Handler
from vehicle.estimators.persisting_errors import GrowingErrors
from vehicle.estimators.settings import shared_arguments
from vehicle.estimators.state import SEVERITY_WARNING, FilterState, Notice, tally_nis
from vehicle.estimators.stores import DenseStore
from vehicle.estimators.updates import Linearized
from vehicle.models import added_states
from vehicle.models import landmarks as slam
from vehicle.models.cooperative import CooperativeRule
from vehicle.models.gnss import gnss_model
from vehicle.models.gnss_error import GnssErrorModel
from vehicle.models.motion import UnicycleMotion
from vehicle.trust.neighbours import MonitorSpec

LOST_AFTER = 8  # sightings in a row failing the gate
RELOCALIZE_SIGMA = np.array([1.0, 1.0, 0.5])  # m, m, rad added to the pose's spread when lost


@dataclass
class KnownMapBook:
    fused: int = 0
    rejected: int = 0
    unknown_landmarks: int = 0
    failed_in_a_row: list[int] = field(default_factory=list)  # landmark ids of the current run of gate failures


class KnownMap:
    """Sightings of surveyed landmarks (module docstring); its book is ``FilterState.landmarks``."""

    def __init__(self, landmarks: tuple[tuple[int, float, float], ...]) -> None:
        self.where = {int(ident): np.array([x, y], dtype=float) for ident, x, y in landmarks}

    def handlers(self) -> dict[type, Handler]:
        """Identified sightings; camera frames are not this filter's."""
        return {m.LandmarkSighting: self.on_sighting}

    def start(self, s: FilterState) -> None:
        s.landmarks = KnownMapBook()
        s.counters.landmarks = len(self.where)

    def initialise(self, s: FilterState) -> None:
        """Nothing to set up: the map is surveyed."""

    def position_reset(self, s: FilterState) -> None:
        """Nothing to do."""

    def recovered(self, s: FilterState) -> None:
        """Nothing to do."""

    def landmark_map(self, s: FilterState) -> None:
        """The surveyed map is not the filter's to report."""
        return None

    def on_sighting(self, fusing: Fusing, msg: m.LandmarkSighting) -> None:
        """One gated range-bearing update against the mapped landmark."""
        fusing.propagate_to(msg.stamp_us)
        s, store = fusing.state, fusing.store
        book = s.landmarks
        where = self.where.get(msg.landmark_id)
        if where is None:
            book.unknown_landmarks += 1
            return
        R = np.array(msg.covariance, dtype=float)
        model = fusing.errors.of_sighting(s, store, ("landmark", msg.landmark_id), msg.stamp_us, R[1, 1])
        predicted, H_pose, _ = slam.observe(np.concatenate([s.x[:3], where]), 3, 0)
        H = np.zeros((2, len(s.x)))
        H[:, :3] = H_pose
        if model:  # range r (1 + k + s_l), bearing beta + b_l, each + white (vehicle.models.added_states)
            H, R, predicted = added_states.persisting_sighting(H, R, predicted, s.x, **model)
        y = np.array([msg.range_m - predicted[0], wrap_angle(msg.bearing_rad - predicted[1])])
        result = store.update(s, y, H, R, fusing.gate)
        tally_nis(s, "landmark", result, 2)
        if result.accepted:
            book.fused += 1
            book.failed_in_a_row = []
            return
        book.rejected += 1
        book.failed_in_a_row.append(msg.landmark_id)
        if len(book.failed_in_a_row) >= LOST_AFTER and len(set(book.failed_in_a_row)) >= 2:
            self._relocalize(fusing, msg.stamp_us)

    def _relocalize(self, fusing: Fusing, t_us: int) -> None:
        """Widen the pose's spread so the map can pull it back (see the module docstring)."""
        s = fusing.state
        failed = len(s.landmarks.failed_in_a_row)
        s.landmarks.failed_in_a_row = []
        fusing.store.set_spread(s, [0, 1, 2], np.diagonal(s.P)[:3] + RELOCALIZE_SIGMA**2)
        s.counters.resets += 1
        text = f"lost track: {failed} landmark sightings in a row failed the gate; re-localizing against the map"
        fusing.say(Notice(t_us, SEVERITY_WARNING, text))


def build(
    *,
    landmarks: tuple[tuple[int, float, float], ...],
    vehicle_id: int,
    spec: SensorSpec,
    gate_probability: float,
    cooperative: CooperativeRule = CooperativeRule(),
    adaptive_window: int = 0,
    store=None,
    monitor: MonitorSpec | None = MonitorSpec(),
) -> Filter:
    """The known-map EKF of vehicle ``vehicle_id`` with the surveyed ``landmarks`` (id, x m, y m)."""
    error = GnssErrorModel.from_spec(spec)
    gnss = gnss_model(error)
    after_wheels = gnss.base_dim + (2 if spec.odom_scale_prior_sigma else 0)
    range_scale = after_wheels if spec.range_scale_prior_sigma else None
    errors = GrowingErrors(
        spec, first_index=after_wheels + (1 if range_scale is not None else 0), range_scale_index=range_scale
    )
    return Filter(
        name="known-map",
        vehicle_id=vehicle_id,
        spec=spec,
        gate_probability=gate_probability,
        gnss=gnss,
        motion=UnicycleMotion(
            gnss_error=error, wheel_scales=bool(spec.odom_scale_prior_sigma), range_scale=range_scale is not None
        ),
        update=Linearized(),
        store=DenseStore() if store is None else store,
        divergence=FullCheck(),
        errors=errors,
        sightings=KnownMap(landmarks),
        cooperative=cooperative,
        adaptive_window=adaptive_window,
        monitor=monitor,
    )


def from_config(config: VehicleProcessConfig, vehicle_id: int, *, reject=None) -> Filter:
    """:func:`build` from a vehicle's configuration (its map is ``vehicle.landmarks``)."""
    return build(landmarks=config.vehicle.landmarks, **shared_arguments(config, vehicle_id))
