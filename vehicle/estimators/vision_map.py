"""The map and the camera front end of ``ekf-slam`` (vision EKF-SLAM paper), also ``ar-ekf-slam``'s
under its map policy: the landmarks [l1x, l1y, l2x, l2y, ...] (m) after the filter's head, and the
book beside them (descriptors, first estimates, a replay's identities). Every camera frame:

1. is judged (garbage frames are counted and reported, never fused);
2. goes through the front end: SIFT (or ORB) keypoints, pixel offsets to range and bearing with the
   ground scale the frame carries (``vehicle.vision.features``);
3. is associated with the landmarks in view: descriptor match with the ratio test, kept when the
   pairs agree on one rigid motion (RANSAC), each then fused by a sequential range-bearing update
   (paper) behind a Mahalanobis gate, with first-estimates Jacobians (Huang et al. 2008, see
   ``vehicle.models.landmarks``) so that loop closures do not make the filter overconfident;
4. adds landmarks: the strongest keypoint of each 30 x 30 px cell (paper's thinning) that matched
   nothing and lies farther than half a cell from every mapped landmark, initialised with the
   paper's ``g(x, z)``, ``Gx``, ``Gz`` in one batch per frame.

A replayed data set (sim.replay) brings landmark sightings with their identities instead of frames: a
mapped one is updated, a new one initialised, the same way, with its persisting errors.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from bus.statistics import gate_threshold
from vehicle.association.methods import METHODS
from vehicle.association.problem import problem
from vehicle.estimators.filter import Filter
from vehicle.estimators.state import FilterState, frozen
from vehicle.models import added_states
from vehicle.models import landmarks as slam
from vehicle.vision import association, features

CELL_PX = 30  # paper's thinning cell
LANDMARK_GATE_P = 0.999  # Mahalanobis gate on each landmark update
CONSENSUS_M = 0.3  # matches must agree on one rigid motion within this [m]
FRAMES_REMEMBERED = 32  # front-end results kept for replays (3.2 s at 10 Hz; the horizon is 0.5 s)
SHORTLIST = 3  # geometric association: each landmark's nearest keypoints by descriptor

Reject = Callable[[str, str, str], None]


@dataclass
class MapBook:
    """The map's book beside x and P: each landmark's descriptor (m, d) and first estimate (m, 2)
    (read-only arrays, replaced by grown copies), the identified landmarks of a replay (id -> map
    index), and what a map policy keeps (``policy``: ar-ekf-slam's range and retired landmarks)."""

    descriptors: np.ndarray | None = None
    first_xy: np.ndarray | None = None
    index_of: dict[int, int] = field(default_factory=dict)
    policy: object = None


class VisionSlamMap:
    """The map and the camera front end of ``ekf-slam`` (module docstring)."""

    def __init__(
        self,
        *,
        head_dim: int,
        detector: str = "sift",
        reject: Reject | None = None,
        first_estimates: bool = True,
        front_end_results: dict | None = None,
        policy: object,
        association: str = "descriptor",
    ) -> None:
        """``front_end_results``: where the front end remembers each frame's keypoints by (stamp, seq);
        estimators fed the same frames (a Monte Carlo comparison) may share one and detect once.
        ``policy``: which landmarks the state keeps (``ekf-slam``'s ``FullMap``: all of them;
        ``ar-ekf-slam``'s ``LocalMap``); ``association``: "descriptor" or a method of
        ``vehicle.association.methods``."""
        self.policy = policy
        self.association = association
        self.last_pairs: list[tuple[int, int]] = []  # the last frame's (keypoint, landmark), for experiments
        self.last_problem: tuple | None = None  # and its (association problem, assignment), geometric only
        cv2.setNumThreads(1)  # one core per vehicle process: OpenCV's thread pool would fight the others for it
        self.head_dim = head_dim
        self._detector = features.make_detector(detector)
        self.norm = cv2.NORM_L2 if detector == "sift" else cv2.NORM_HAMMING
        self._gate = gate_threshold(2, LANDMARK_GATE_P)
        self._reject = reject or (lambda reason, where, detail: None)
        self.first_estimates = first_estimates  # False: Jacobians at the current estimates (the paper's EKF)
        self._judged_until_us = -1  # garbage frames are reported once, replays or not
        self._seen_frames: dict[tuple[int, int], tuple] = {} if front_end_results is None else front_end_results

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

    def start(self, s: FilterState) -> None:
        s.landmarks = MapBook(policy=self.policy.start())

    def initialise(self, f: Filter) -> None:
        s = f.state
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

    def on_frame(self, f: Filter, frame: m.CameraFrame) -> None:
        reason = features.garbage_reason(frame.pixels)
        if reason is not None:
            if frame.stamp_us > self._judged_until_us:  # a replay meets the same frame again
                self._judged_until_us = frame.stamp_us
                self._reject("garbage_frame", f"camera of vehicle {f.vehicle_id}", reason)
            return
        f.propagate_to(frame.stamp_us)
        self.policy.before_frame(f, self)
        found, z, R = self._front_end(frame, f.spec.keypoint_sigma_px)
        size, scale = frame.pixels.shape[0], frame.metres_per_pixel
        half_extent_m = 0.5 * size * scale
        matched = self._update_matched(f, found, z, R, half_extent_m=half_extent_m)
        matched |= self.policy.reenter(f, self, found, z, R, matched, half_extent_m)
        self._add_landmarks(f.state, found, z, R, matched, cell_m=CELL_PX * scale)
        f.state.counters.frames_used += 1

    def _front_end(self, frame: m.CameraFrame, sigma_px: float) -> tuple[features.Features, np.ndarray, np.ndarray]:
        """Keypoints, [range, bearing] (k, 2) and their covariances (k, 2, 2) of a frame; remembered
        for the few frames a fusion-horizon replay may meet again (a pure function of the pixels)."""
        key = (frame.stamp_us, frame.seq)
        if key not in self._seen_frames:
            found = features.detect(np.ascontiguousarray(frame.pixels), self._detector)
            size, scale = frame.pixels.shape[0], frame.metres_per_pixel
            z = features.range_bearing(found.points_px, size, scale)
            R = features.pixel_noise_to_range_bearing(found.points_px, size, scale, sigma_px)
            self._seen_frames[key] = (found, z, R)
            while len(self._seen_frames) > FRAMES_REMEMBERED:
                self._seen_frames.pop(next(iter(self._seen_frames)))
        return self._seen_frames[key]

    def remembered(self, stamp_us: int, seq: int) -> tuple | None:
        """The front end's (keypoints, z, R) of a recent frame, if still remembered (experiments)."""
        return self._seen_frames.get((stamp_us, seq))

    def _update_matched(
        self, f: Filter, found: features.Features, z: np.ndarray, R: np.ndarray, *, half_extent_m: float
    ) -> set[int]:
        """Sequential updates with the keypoints matched to landmarks in view; returns the keypoints
        that matched a landmark (fused or gated out)."""
        s, book = f.state, f.state.landmarks
        mapped = self.landmarks_xy(s)
        visible = association.in_view(mapped, s.x[:3], half_extent_m)
        if self.association != "descriptor":
            return self._update_associated(f, found, z, R, visible)
        pairs = association.match(found.descriptors, book.descriptors[visible], self.norm) if len(visible) else []
        if pairs:
            seen = np.array([z[i] for i, _ in pairs])
            measured = np.stack([seen[:, 0] * np.cos(seen[:, 1]), seen[:, 0] * np.sin(seen[:, 1])], axis=1)
            predicted = association.to_body(mapped[[visible[row] for _, row in pairs]], s.x[:3])
            agree = association.rigidly_consistent(predicted, measured, CONSENSUS_M)
            pairs = [pair for pair, ok in zip(pairs, agree.tolist()) if ok]
        updated = 0
        for i, row in pairs:
            updated += int(self.update_landmark(f, int(visible[row]), z[i], R[i]))
        s.counters.landmarks_updated = updated
        self.last_pairs = [(i, int(visible[row])) for i, row in pairs]
        return {i for i, _ in pairs}

    def _update_associated(
        self, f: Filter, found: features.Features, z: np.ndarray, R: np.ndarray, visible: np.ndarray
    ) -> set[int]:
        """Geometric association (``vehicle.association``) among each visible landmark's descriptor
        shortlist, then the sequential updates; returns the keypoints paired."""
        s = f.state
        self.last_problem = None
        if not len(visible) or s.landmarks.descriptors is None:
            s.counters.landmarks_updated, self.last_pairs = 0, []
            return set()
        shortlisted = association.shortlist(found.descriptors, s.landmarks.descriptors[visible], self.norm, SHORTLIST)
        observations = sorted({i for i, _ in shortlisted})
        pairs: list[tuple[int, int]] = []
        if observations:
            column = {i: a for a, i in enumerate(observations)}
            allowed = np.zeros((len(observations), len(visible)), dtype=bool)
            for i, row in shortlisted:
                allowed[column[i], row] = True
            predicted, C = self.predictions(s, visible)
            p = problem(
                z[observations], R[observations], predicted, C, allowed=allowed, gate_probability=LANDMARK_GATE_P
            )
            rng = np.random.default_rng([f.vehicle_id, s.time_us])  # a replayed frame is associated alike
            assignment = METHODS[self.association](p, rng)
            self.last_problem = (p, assignment)
            pairs = [(observations[a], int(row)) for a, row in enumerate(assignment.tolist()) if row >= 0]
        updated = sum(int(self.update_landmark(f, int(visible[row]), z[i], R[i])) for i, row in pairs)
        s.counters.landmarks_updated = updated
        self.last_pairs = [(i, int(visible[row])) for i, row in pairs]
        return {i for i, _ in pairs}

    def predictions(self, s: FilterState, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Predicted observations (m, 2) of mapped landmarks ``rows`` and their joint covariance
        C = H P H^T (2m, 2m) (Jacobians at the current estimate)."""
        m = len(rows)
        predicted = np.zeros((m, 2))
        H = np.zeros((2 * m, 3 + 2 * m))
        for a, j in enumerate(rows.tolist()):
            predicted[a], H[2 * a : 2 * a + 2, :3], H[2 * a : 2 * a + 2, 3 + 2 * a : 5 + 2 * a] = slam.observe(
                s.x, self.head_dim, j
            )
        columns = np.concatenate([[0, 1, 2], (self.head_dim + 2 * rows[:, None] + np.arange(2)).ravel()])
        return predicted, H @ s.P[np.ix_(columns, columns)] @ H.T

    def update_landmark(self, f: Filter, j: int, z: np.ndarray, R: np.ndarray) -> bool:
        """The paper's gated range-bearing update with mapped landmark j; True when fused."""
        s = f.state
        predicted, H_pose, H_landmark = slam.observe(s.x, self.head_dim, j, self._linearize_at(s, j))
        k = self.head_dim + 2 * j
        y = np.array([z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
        H = np.hstack([H_pose, H_landmark])
        result = f.store.update(s, y, H, R, self._gate, [0, 1, 2, k, k + 1])
        f.tally_nis("landmark", result, 2)
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

    def on_sighting(self, f: Filter, msg: m.LandmarkSighting) -> None:
        """The paper's update if the landmark is mapped, else its initialisation (g, Gx, Gz).
        Identities come with the data, so no association is needed."""
        f.propagate_to(msg.stamp_us)
        self.policy.before_sighting(f, self, msg.stamp_us)
        s, book = f.state, f.state.landmarks
        z = np.array([msg.range_m, msg.bearing_rad])
        j = book.index_of.get(msg.landmark_id)
        if j is None and s.counters.landmarks >= self.policy.capacity:
            return
        R = np.asarray(msg.covariance, dtype=float)
        errors = f.errors
        first = errors.index_of(f, ("landmark", msg.landmark_id), msg.stamp_us, R[1, 1]) if errors.per_subject else None
        if j is not None:
            self._update_identified(f, j, z, R, first)
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

    def _update_identified(self, f: Filter, j: int, z: np.ndarray, R: np.ndarray, first: int | None) -> None:
        """The paper's gated update with mapped landmark j; with its error states from ``first`` on,
        the model of added_states.persisting_sighting over [x, y, theta, errors, l_jx, l_jy]."""
        if first is None:
            self.update_landmark(f, j, z, R)
            return
        s, per = f.state, f.errors.per_subject
        predicted, H_pose, H_landmark = slam.observe(s.x, self.head_dim, j, self._linearize_at(s, j))
        k = self.head_dim + 2 * j
        idx = [0, 1, 2, *range(first, first + per), k, k + 1]
        H = np.hstack([H_pose, np.zeros((2, per)), H_landmark])
        model = added_states.in_columns(f.errors.model(s, first), idx)
        H, R, predicted = added_states.persisting_sighting(H, R, predicted, s.x, **model)
        y = np.array([z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
        f.tally_nis("landmark", f.store.update(s, y, H, R, self._gate, idx), 2)
