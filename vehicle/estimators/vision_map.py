"""The map of ``ekf-slam`` (vision EKF-SLAM paper), also ``ar-ekf-slam``'s under its map policy: the
landmarks [l1x, l1y, ...] (m) after the filter's head, and the book beside them (descriptors, first
estimates, a replay's identities). Every camera frame is judged and read by the camera front end
(vehicle.estimators.camera_front_end), paired with the landmarks in view (map_association), each pair
fused by the paper's sequential range-bearing update behind a Mahalanobis gate with first-estimates
Jacobians (Huang et al. 2008, ``vehicle.models.landmarks``: loop closures do not make the filter
overconfident); then the strongest keypoint of each 30 x 30 px cell (the paper's thinning) that paired
with nothing and lies farther than half a cell from every landmark is added with the paper's
``g(x, z)``, ``Gx``, ``Gz``, in one batch per frame. A replayed data set brings landmark sightings with
their identities instead: a mapped one is updated, a new one initialised, with its persisting errors.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from bus.statistics import gate_threshold
from vehicle.association import descriptors as matching
from vehicle.estimators import map_association
from vehicle.estimators.camera_front_end import CameraFrontEnd
from vehicle.estimators.map_association import LANDMARK_GATE_P
from vehicle.estimators.parts import Fusing, Handler, Reject
from vehicle.estimators.state import FilterState, frozen, tally_nis
from vehicle.models import added_states
from vehicle.models import landmarks as slam
from vehicle.vision import features

CELL_PX = 30  # paper's thinning cell


class MapPolicy(Protocol):
    """Which landmarks the state keeps: ``ekf-slam``'s ``FullMap`` (all of them, up to its capacity),
    ``ar-ekf-slam``'s ``LocalMap`` (those within the adaptive range; the rest retired). Its book is
    ``MapBook.policy``."""

    capacity: int

    def start(self) -> Any: ...
    def before_frame(self, s: FilterState, the_map: VisionSlamMap) -> None: ...
    def before_sighting(self, s: FilterState, the_map: VisionSlamMap, stamp_us: int) -> None: ...
    def reenter(
        self,
        s: FilterState,
        the_map: VisionSlamMap,
        found: features.Features,
        z: np.ndarray,
        R: np.ndarray,
        matched: set[int],
        half_extent_m: float,
    ) -> set[int]: ...
    def occupied(self, s: FilterState) -> np.ndarray | None: ...
    def take_retired(self, s: FilterState, ident: int) -> tuple[np.ndarray, np.ndarray] | None: ...
    def reentered(self, s: FilterState, k: int, retired: tuple[np.ndarray, np.ndarray]) -> None: ...


@dataclass
class MapBook:
    """The map's book beside x and P: each landmark's descriptor (m, d) and first estimate (m, 2)
    (read-only arrays, replaced by grown copies), the identified landmarks of a replay (id -> map
    index), and what a map policy keeps (``policy``: ar-ekf-slam's range and retired landmarks)."""

    descriptors: np.ndarray | None = None
    first_xy: np.ndarray | None = None
    index_of: dict[int, int] = field(default_factory=dict)
    policy: Any = None  # the map policy's own book (MapPolicy.start)


class VisionSlamMap:
    """The map and the camera front end of ``ekf-slam`` (module docstring)."""

    def __init__(
        self,
        *,
        head_dim: int,
        vehicle_id: int,
        keypoint_sigma_px: float,
        detector: str = "sift",
        reject: Reject | None = None,
        first_estimates: bool = True,
        front_end_results: dict | None = None,
        policy: MapPolicy,
        association: str = "descriptor",
    ) -> None:
        """``front_end_results``: where the front end remembers each frame's keypoints by (stamp, seq);
        estimators fed the same frames (a Monte Carlo comparison) may share one and detect once.
        ``policy``: which landmarks the state keeps (``ekf-slam``'s ``FullMap``: all of them;
        ``ar-ekf-slam``'s ``LocalMap``); ``association``: "descriptor" or a method of
        ``vehicle.association.methods``; ``keypoint_sigma_px``: the keypoints' position noise (the
        datasheet's)."""
        self.vehicle_id = vehicle_id
        self.front_end = CameraFrontEnd(
            vehicle_id=vehicle_id,
            keypoint_sigma_px=keypoint_sigma_px,
            detector=detector,
            reject=reject,
            results=front_end_results,
        )
        self.norm = self.front_end.norm
        self.policy = policy
        self.association = association
        self.last_pairs: list[tuple[int, int]] = []  # the last frame's (keypoint, landmark), for experiments
        self.last_problem: tuple | None = None  # and its (association problem, assignment), geometric only
        self.head_dim = head_dim
        self._gate = gate_threshold(2, LANDMARK_GATE_P)
        self.first_estimates = first_estimates  # False: Jacobians at the current estimates (the paper's EKF)

    def landmarks_xy(self, s: FilterState) -> np.ndarray:
        """Mapped landmarks (m, 2) [m]."""
        return s.x[self.head_dim :].reshape(-1, 2) if s.x is not None else np.zeros((0, 2))

    def landmark_map(self, s: FilterState) -> tuple[np.ndarray, np.ndarray] | None:
        """Landmark positions (m, 2) and their covariances (m, 2, 2); None before the first landmark."""
        count = s.counters.landmarks
        if s.x is None or count == 0:
            return None
        i = self.head_dim + 2 * np.arange(count)
        cov = np.empty((count, 2, 2))
        cov[:, 0, 0], cov[:, 1, 1] = s.P[i, i], s.P[i + 1, i + 1]
        cov[:, 0, 1] = cov[:, 1, 0] = s.P[i, i + 1]
        return self.landmarks_xy(s).copy(), cov

    # -- the state's life --------------------------------------------------------------------

    def handlers(self) -> dict[type, Handler]:
        """Camera frames, and a replay's identified sightings."""
        return {m.CameraFrame: self.on_frame, m.LandmarkSighting: self.on_sighting}

    def start(self, s: FilterState) -> None:
        s.landmarks = MapBook(policy=self.policy.start())

    def initialise(self, s: FilterState) -> None:
        s.landmarks = MapBook(policy=self.policy.start())
        s.prior_xy = frozen(s.x[:2].copy())
        s.counters.landmarks = 0

    def position_reset(self, s: FilterState) -> None:
        s.prior_xy = frozen(s.x[:2].copy())  # the jump is not motion

    def recovered(self, s: FilterState) -> None:
        """The fallback's map, and the descriptors of the landmarks it had."""
        book = s.landmarks
        if s.x is None:
            s.landmarks, s.counters.landmarks = MapBook(policy=self.policy.start()), 0
            return
        kept = s.counters.landmarks = (len(s.x) - self.head_dim) // 2
        book.descriptors = None if book.descriptors is None else book.descriptors[:kept]
        book.first_xy = None if book.first_xy is None else book.first_xy[:kept]
        book.index_of = {ident: j for ident, j in book.index_of.items() if j < kept}
        s.prior_xy = frozen(s.x[:2].copy())

    # -- camera frames -----------------------------------------------------------------------

    def on_frame(self, fusing: Fusing, frame: m.CameraFrame) -> None:
        if not self.front_end.usable(frame):
            return
        fusing.propagate_to(frame.stamp_us)
        s = fusing.state
        self.policy.before_frame(s, self)
        found, z, R = self.front_end.observe(frame)
        size, scale = frame.pixels.shape[0], frame.metres_per_pixel
        half_extent_m = 0.5 * size * scale
        matched = self._update_matched(fusing, found, z, R, half_extent_m=half_extent_m)
        matched |= self.policy.reenter(s, self, found, z, R, matched, half_extent_m)
        self._add_landmarks(s, found, z, R, matched, cell_m=CELL_PX * scale)
        s.counters.frames_used += 1

    def _update_matched(
        self, fusing: Fusing, found: features.Features, z: np.ndarray, R: np.ndarray, *, half_extent_m: float
    ) -> set[int]:
        """Sequential updates with the keypoints paired with landmarks in view (map_association);
        returns the keypoints paired (fused or gated out)."""
        s = fusing.state
        mapped = self.landmarks_xy(s)
        visible = matching.in_view(mapped, s.x[:3], half_extent_m)
        if self.association == "descriptor":
            pairs = map_association.by_descriptor(
                found, z, mapped, visible, s.landmarks.descriptors, s.x[:3], self.norm
            )
        else:
            seed = [self.vehicle_id, s.time_us]
            pairs, self.last_problem = map_association.by_geometry(
                self.association, found, z, R, visible, s, self.head_dim, self.norm, seed
            )
        updated = sum(int(self.update_landmark(fusing, int(visible[row]), z[i], R[i])) for i, row in pairs)
        s.counters.landmarks_updated = updated
        self.last_pairs = [(i, int(visible[row])) for i, row in pairs]
        return {i for i, _ in pairs}

    def update_landmark(self, fusing: Fusing, j: int, z: np.ndarray, R: np.ndarray) -> bool:
        """The paper's gated range-bearing update with mapped landmark j; True when fused."""
        s = fusing.state
        predicted, H_pose, H_landmark = slam.observe(s.x, self.head_dim, j, self._linearize_at(s, j))
        k = self.head_dim + 2 * j
        y = np.array([z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
        H = np.hstack([H_pose, H_landmark])
        result = fusing.store.update(s, y, H, R, self._gate, [0, 1, 2, k, k + 1])
        tally_nis(s, "landmark", result, 2)
        return result.accepted

    def _linearize_at(self, s: FilterState, j: int) -> tuple[np.ndarray, np.ndarray] | None:
        """First estimates: the position as last propagated and the landmark's first estimate."""
        return (s.prior_xy, s.landmarks.first_xy[j]) if self.first_estimates else None

    def _add_landmarks(
        self,
        s: FilterState,
        found: features.Features,
        z: np.ndarray,
        R: np.ndarray,
        matched: set[int],
        *,
        cell_m: float,
    ) -> None:
        """New landmarks from the thinned keypoints that matched nothing and lie farther than half a
        cell from the map (paper's initialisation, one batch per frame)."""
        room = self.policy.capacity - s.counters.landmarks
        thinned = features.thin_indices(found.points_px, found.responses, CELL_PX).tolist()
        keep = [i for i in thinned if i not in matched]
        if not keep or room <= 0:
            return
        where = features.body_to_world(s.x[:3], z[keep])
        mapped = self.landmarks_xy(s)
        outside = self.policy.occupied(s)
        if outside is not None and len(outside):
            mapped = np.vstack([mapped, outside])
        if len(mapped):
            gap = np.min(np.hypot(*(where[:, None, :] - mapped[None, :, :]).transpose(2, 0, 1)), axis=1)
            keep = [i for i, g in zip(keep, gap.tolist()) if g > 0.5 * cell_m]
        keep = keep[:room]
        if not keep:
            return
        s.x, s.P = slam.add_landmarks(s.x, s.P, z[keep], R[keep])
        self.grow_book(s, found.descriptors[keep], len(keep))

    def grow_book(self, s: FilterState, descriptors: np.ndarray | None, added: int) -> None:
        """The book follows ``added`` landmarks appended to the state (their descriptors, if any)."""
        book = s.landmarks
        if descriptors is not None:
            grown = descriptors.copy() if book.descriptors is None else np.vstack([book.descriptors, descriptors])
            book.descriptors = frozen(grown)
        first = s.x[-2 * added :].reshape(-1, 2).copy()
        book.first_xy = frozen(first if book.first_xy is None else np.vstack([book.first_xy, first]))
        s.counters.landmarks += added

    # -- identified sightings (a replayed data set) -------------------------------------------

    def on_sighting(self, fusing: Fusing, msg: m.LandmarkSighting) -> None:
        """The paper's update if the landmark is mapped, else its initialisation (g, Gx, Gz).
        Identities come with the data, so no association is needed."""
        fusing.propagate_to(msg.stamp_us)
        s = fusing.state
        self.policy.before_sighting(s, self, msg.stamp_us)
        book = s.landmarks
        z = np.array([msg.range_m, msg.bearing_rad])
        j = book.index_of.get(msg.landmark_id)
        if j is None and s.counters.landmarks >= self.policy.capacity:
            return
        R = np.asarray(msg.covariance, dtype=float)
        errors = fusing.errors
        key = ("landmark", msg.landmark_id)
        first = errors.index_of(s, fusing.store, key, msg.stamp_us, R[1, 1]) if errors.per_subject else None
        if j is not None:
            self._update_identified(fusing, j, z, R, first)
            return
        retired = self.policy.take_retired(s, msg.landmark_id)
        if first is None:
            s.x, s.P = slam.add_landmarks(s.x, s.P, z[None, :], msg.covariance)
        else:
            model = errors.model(s, first)
            range_sigma, bearing_var = model.get("range_sigma_per_m", 0.0), model.get("bearing_var", 0.0)
            white = added_states.white_part(R, msg.range_m, range_sigma, bearing_var)
            s.x, s.P = slam.add_landmark_with_errors(
                s.x, s.P, z, white, model.get("range_state"), model.get("bearing_state")
            )
        book.index_of = {**book.index_of, msg.landmark_id: s.counters.landmarks}
        self.grow_book(s, None, 1)
        if retired is not None:
            self.policy.reentered(s, len(s.x) - 2, retired)

    def _update_identified(self, fusing: Fusing, j: int, z: np.ndarray, R: np.ndarray, first: int | None) -> None:
        """The paper's gated update with mapped landmark j; with its error states from ``first`` on,
        the model of added_states.persisting_sighting over [x, y, theta, errors, l_jx, l_jy]."""
        if first is None:
            self.update_landmark(fusing, j, z, R)
            return
        s, per = fusing.state, fusing.errors.per_subject
        predicted, H_pose, H_landmark = slam.observe(s.x, self.head_dim, j, self._linearize_at(s, j))
        k = self.head_dim + 2 * j
        idx = [0, 1, 2, *range(first, first + per), k, k + 1]
        H = np.hstack([H_pose, np.zeros((2, per)), H_landmark])
        model = added_states.in_columns(fusing.errors.model(s, first), idx)
        H, R, predicted = added_states.persisting_sighting(H, R, predicted, s.x, **model)
        y = np.array([z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
        tally_nis(s, "landmark", fusing.store.update(s, y, H, R, self._gate, idx), 2)
