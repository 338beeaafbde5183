"""``ekf-slam``: vision EKF-SLAM (vision EKF-SLAM paper) on top of the default ``ekf``.

The state is the unicycle EKF's pose block [x, y, theta, gyro_bias] followed by the map
[l1x, l1y, l2x, l2y, ...] (m); odometry, IMU, GNSS (when there is any) and cooperative fixes act as
in ``ekf``, the prediction moves the pose block and its cross-covariances in place
(``ekf_slam_core.predict_pose``). Every camera frame:

1. is judged (garbage frames are counted and reported, never fused);
2. goes through the front end: SIFT (or ORB) keypoints, pixel offsets to range and bearing with the
   ground scale the frame carries (``vehicle.vision.features``);
3. is associated with the landmarks in view: descriptor match with the ratio test, kept when the
   pairs agree on one rigid motion (RANSAC), each then fused by a sequential range-bearing update
   (paper) behind a Mahalanobis gate, in place on P, with first-estimates Jacobians (Huang et
   al. 2008, see ``ekf_slam_core``) so that loop closures do not make the filter overconfident;
4. adds landmarks: the strongest keypoint of each 30 x 30 px cell (paper's thinning) that matched
   nothing and lies farther than half a cell from every mapped landmark, initialised with the
   paper's ``g(x, z)``, ``Gx``, ``Gz`` in one batch per frame.

A replayed data set (sim.replay) brings landmark sightings with their identities instead of frames: a
mapped one is updated, a new one initialised, the same way. Errors that persist, each on when its
datasheet field is nonzero, as in ``known-map`` (vehicle.added_states): the wheel odometry's speed
and yaw-rate scale errors (two states after the pose), and the camera's time-correlated range and
bearing errors, Gauss-Markov states per landmark in view held in ``ERROR_SLOTS`` slots after those
(a slot: [s, b], or the one of them that is on): a landmark seen again gets its slot back, a new one
takes a free slot or the one of the landmark seen longest ago (its states marginalized: by then they
hardly correlate with a new reading); robot sightings (cooperative) take slots the same way, one per
robot seen and one per robot that sees this one. The state is then [pose (4), k_v, k_w, slots, map]:
``head_dim`` states before the map.

Pure: no bus, no clock. Fusion-horizon snapshots copy (x, P) only where the horizon asks for one;
the fallback for divergence recovery is refreshed once per ``GOOD_PERIOD_US``, not every cycle.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import cv2
import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from bus.config import SensorSpec
from vehicle import added_states
from vehicle import ekf_slam_core as slam
from vehicle import unicycle_ekf as ekf
from vehicle.cooperative import CooperativeRule, Correction
from vehicle.ekf import gate_threshold
from vehicle.estimators.ekf import DIVERGENCE_FLOOR, DIVERGENCE_INFLATION, UnicycleEkf
from vehicle.estimators.sighting_errors import SightingErrors, Subject
from vehicle.vision import association, features

POSE_DIM = 4
CELL_PX = 30                 # paper's thinning cell
LANDMARK_GATE_P = 0.999      # Mahalanobis gate on each landmark update
GOOD_PERIOD_US = 1_000_000   # divergence fallback refreshed this often (it is an n x n copy)
CONSENSUS_M = 0.3           # matches must agree on one rigid motion within this [m]
FRAMES_REMEMBERED = 32      # front-end results kept for replays (3.2 s at 10 Hz; the horizon is 0.5 s)
MAX_LANDMARKS = 2000         # the map stops growing here (update cost is O(n^2))
ERROR_SLOTS = 8              # error-state slots: landmarks (and robots) in view at once, with their recent past

Reject = Callable[[str, str, str], None]


class EkfSlam(SightingErrors, UnicycleEkf):
    """Vision EKF-SLAM: see the module docstring."""

    name = "ekf-slam"
    models_gnss_error = False  # the map's camera fixes anchor the position; GNSS error taken as white

    def __init__(self, *, vehicle_id: int, spec: SensorSpec, gate_probability: float, altitude_m: float,
                 detector: str = "sift", reject: Reject | None = None, first_estimates: bool = True,
                 cooperative: CooperativeRule = CooperativeRule(), adaptive_window: int = 0,
                 front_end_results: dict | None = None) -> None:
        """``front_end_results``: where the front end remembers each frame's keypoints by (stamp, seq);
        estimators fed the same frames (a Monte Carlo comparison) may share one and detect once."""
        super().__init__(vehicle_id=vehicle_id, spec=spec, gate_probability=gate_probability, altitude_m=altitude_m,
                         cooperative=cooperative, adaptive_window=adaptive_window)
        cv2.setNumThreads(1)  # one core per vehicle process: OpenCV's thread pool would fight the others for it
        self._detector = features.make_detector(detector)
        self._norm = cv2.NORM_L2 if detector == "sift" else cv2.NORM_HAMMING
        self._landmark_gate = gate_threshold(2, LANDMARK_GATE_P)
        self._reject = reject or (lambda reason, where, detail: None)
        self._first_estimates = first_estimates  # False: Jacobians at the current estimates (the paper's EKF)
        self.descriptors: np.ndarray | None = None  # (m, d), replaced (never changed in place) as the map grows
        self.first_xy: np.ndarray | None = None     # (m, 2) landmarks' first estimates (FEJ), replaced likewise
        self._prior_xy: np.ndarray | None = None    # position as last propagated, before any update (FEJ)
        self._good_until_us = -1
        self._judged_until_us = -1  # garbage frames are reported once, replays or not
        self._seen_frames: dict[tuple[int, int], tuple] = {} if front_end_results is None else front_end_results
        # ^ front-end results by (stamp, seq), oldest first
        self._slot: dict[int, int] = {}  # identified landmarks (replayed sightings): id -> map index; replaced, never changed
        self._scale_sigma = spec.odom_scale_prior_sigma
        self._init_sighting_errors(spec)
        self._first_slot = POSE_DIM + (2 if self._scale_sigma else 0)
        self.head_dim = self._first_slot + ERROR_SLOTS * self._per_subject
        # each slot state's tau and stationary variance; the bearing's is the datasheet's until a subject
        # takes the slot, then that of its sightings
        self._slot_taus, self._slot_vars = (np.tile([pair[i] for pair in self._subject_states(spec.bearing_sigma_rad**2)],
                                                    ERROR_SLOTS) for i in (0, 1))
        self._slot_of: dict[Subject, int] = {}  # sighted subject -> index of its slot's first state
        self._last_seen_us: dict[Subject, int] = {}

    @property
    def landmarks_xy(self) -> np.ndarray:
        """Mapped landmarks (m, 2) [m]."""
        return self.x[self.head_dim:].reshape(-1, 2) if self.x is not None else np.zeros((0, 2))

    def handle(self, topic: str, msg: Any) -> None:
        if isinstance(msg, m.CameraFrame):
            if self.x is not None and msg.stamp_us >= self.time_us:
                self._on_frame(msg)
            elif self.x is not None:
                self.counters.stale += 1
            return
        super().handle(topic, msg)

    def _initialise(self, pose: np.ndarray, covariance: np.ndarray, stamp_us: int) -> None:
        super()._initialise(pose, covariance, stamp_us)
        variances = [self._scale_sigma**2] * (2 if self._scale_sigma else 0) + self._slot_vars.tolist()
        self.x, self.P = added_states.append_states(self.x, self.P, np.array(variances))
        self._slot_of, self._last_seen_us = {}, {}
        self.descriptors, self.first_xy, self._prior_xy = None, None, self.x[:2].copy()
        self.counters.landmarks, self._slot = 0, {}

    def _predict(self, speed: float, rate: float, dt: float, **noise: Any) -> None:
        """The pose block moves; landmarks stay; cross-covariances follow in place. F's position-heading
        terms are the displacement between propagated estimates (first-estimates Jacobian). The
        scale states scale the inputs, the range-error states decay (module docstring)."""
        coupling = None
        if self._scale_sigma:  # a fresh gyro's rate is not the wheels'
            speed, rate, noise, coupling = added_states.scaled_inputs(self.x, POSE_DIM, speed, rate, dt, noise,
                                                                      wheel_rate=not noise.get("use_bias"))
        pose_next, F, Q = ekf.motion_model(self.x[:POSE_DIM], speed, rate, dt, **noise)
        if self._first_estimates and self._prior_xy is not None:
            F[0, 2], F[1, 2] = -(pose_next[1] - self._prior_xy[1]), pose_next[0] - self._prior_xy[0]
        head = self.head_dim
        if head > POSE_DIM:
            decay, decay_var = added_states.decays(dt, self._slot_taus, self._slot_vars)
            F, Q = added_states.transition(head, F, Q, coupling, added_states.SCALE_WALK_PER_RTSEC**2 * dt, decay,
                                           decay_var, self._first_slot)
            tail = self.x[POSE_DIM:head].copy()
            tail[self._first_slot - POSE_DIM:] *= decay
            pose_next = np.concatenate([pose_next, tail])
        slam.predict_pose(self.x, self.P, F, Q, pose_next)
        self._prior_xy = pose_next[:2].copy()

    def _apply_correction(self, correction: Correction) -> None:
        """The map follows the pose in place (no n x n temporaries)."""
        slam.apply_correction_in_place(self.x, self.P, correction)

    def _gnss_update(self, fix: m.GnssFix) -> None:
        slam.update_in_place(self.x, self.P, [0, 1], np.eye(2), fix.position_m - self.x[:2], fix.covariance_m2,
                             self._gate)

    def _on_frame(self, frame: m.CameraFrame) -> None:
        reason = features.garbage_reason(frame.pixels)
        if reason is not None:
            if frame.stamp_us > self._judged_until_us:  # a replay meets the same frame again
                self._judged_until_us = frame.stamp_us
                self._reject("garbage_frame", f"camera of vehicle {self.vehicle_id}", reason)
            return
        self._propagate_to(frame.stamp_us)
        found, z, R = self._front_end(frame)
        size, scale = frame.pixels.shape[0], frame.metres_per_pixel
        matched = self._update_matched(found, z, R, half_extent_m=0.5 * size * scale)
        self._add_landmarks(found, z, R, matched, cell_m=CELL_PX * scale)
        self.counters.frames_used += 1

    def _landmark_sighting(self, msg: m.LandmarkSighting) -> None:
        """A replayed sighting of an identified landmark: the paper's update if it is mapped, else its
        initialisation (g, Gx, Gz). Identities come with the data, so no association is needed."""
        self._propagate_to(msg.stamp_us)
        z = np.array([msg.range_m, msg.bearing_rad])
        j = self._slot.get(msg.landmark_id)
        if j is None and self.counters.landmarks >= MAX_LANDMARKS:
            return
        R = np.asarray(msg.covariance, dtype=float)
        error = self._error_index(("landmark", msg.landmark_id), msg.stamp_us, R[1, 1]) if self._per_subject else None
        if j is not None:
            self._update_identified(j, z, R, error)
            return
        if error is None:
            self.x, self.P = slam.add_landmarks(self.x, self.P, z[None, :], msg.covariance)
        else:
            model = self._error_model(error)
            white = added_states.white_part(R, msg.range_m, model.get("range_sigma_per_m", 0.0),
                                            model.get("bearing_var", 0.0))
            self.x, self.P = slam.add_landmark_with_errors(self.x, self.P, z, white, model.get("range_state"),
                                                           model.get("bearing_state"))
        first = self.x[-2:].reshape(1, 2).copy()
        self.first_xy = first if self.first_xy is None else np.vstack([self.first_xy, first])
        self._slot = {**self._slot, msg.landmark_id: self.counters.landmarks}
        self.counters.landmarks += 1

    def _update_identified(self, j: int, z: np.ndarray, R: np.ndarray, error: int | None) -> None:
        """The paper's gated update with mapped landmark j; with its error states from ``error`` on,
        the model of vehicle.added_states.persisting_sighting over [x, y, theta, errors, l_jx, l_jy]."""
        linearize_at = (self._prior_xy, self.first_xy[j]) if self._first_estimates else None
        if error is None:
            slam.update(self.x, self.P, self.head_dim, j, z, R, self._landmark_gate, linearize_at=linearize_at)
            return
        predicted, H_pose, H_landmark = slam.observe(self.x, self.head_dim, j, linearize_at)
        k = self.head_dim + 2 * j
        idx = [0, 1, 2, *range(error, error + self._per_subject), k, k + 1]
        H = np.hstack([H_pose, np.zeros((2, self._per_subject)), H_landmark])
        H, R, predicted = added_states.persisting_sighting(H, R, predicted, self.x,
                                                           **added_states.in_columns(self._error_model(error), idx))
        y = np.array([z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
        slam.update_in_place(self.x, self.P, idx, H, y, R, self._landmark_gate)

    def _stationary_variance(self, index: int) -> float:
        return float(self._slot_vars[index - self._first_slot])

    def _error_index(self, key: Subject, t_us: int, bearing_var: float) -> int:
        """The index of the slot (its first error state) of the sighted subject ``key`` (a landmark, a
        robot seen, a robot seeing this one): its own slot if it has one, else a free slot or the slot
        of the subject seen longest ago, reset to 0 with the stationary variances (the bearing's a
        fraction of ``bearing_var``, the sighting's reported one)."""
        self._last_seen_us = {**self._last_seen_us, key: t_us}
        slot = self._slot_of.get(key)
        if slot is not None:
            return slot
        taken = set(self._slot_of.values())
        free = [i for i in range(self._first_slot, self.head_dim, self._per_subject) if i not in taken]
        owners = dict(self._slot_of)
        if free:
            slot = free[0]
        else:
            oldest = min(owners, key=lambda ident: self._last_seen_us[ident])
            slot = owners.pop(oldest)
        states = list(range(slot, slot + self._per_subject))
        within = slice(slot - self._first_slot, slot - self._first_slot + self._per_subject)
        self._slot_vars = self._slot_vars.copy()  # replaced, never changed in place (snapshots share it)
        self._slot_vars[within] = [variance for _, variance in self._subject_states(bearing_var)]
        self.x[states] = 0.0
        added_states.set_spread(self.P, states, self._slot_vars[within])
        self._slot_of = {**owners, key: slot}
        return slot

    def _front_end(self, frame: m.CameraFrame) -> tuple[features.Features, np.ndarray, np.ndarray]:
        """Keypoints, [range, bearing] (k, 2) and their covariances (k, 2, 2) of a frame; remembered
        for the few frames a fusion-horizon replay may meet again (a pure function of the pixels)."""
        key = (frame.stamp_us, frame.seq)
        if key not in self._seen_frames:
            found = features.detect(np.ascontiguousarray(frame.pixels), self._detector)
            size, scale = frame.pixels.shape[0], frame.metres_per_pixel
            z = features.range_bearing(found.points_px, size, scale)
            R = features.pixel_noise_to_range_bearing(found.points_px, size, scale, self._spec.keypoint_sigma_px)
            self._seen_frames[key] = (found, z, R)
            while len(self._seen_frames) > FRAMES_REMEMBERED:
                self._seen_frames.pop(next(iter(self._seen_frames)))
        return self._seen_frames[key]

    def _update_matched(self, found: features.Features, z: np.ndarray, R: np.ndarray, *, half_extent_m: float) -> set[int]:
        """Sequential updates with the keypoints matched to landmarks in view; returns the keypoints
        that matched a landmark (fused or gated out)."""
        visible = association.in_view(self.landmarks_xy, self.x[:3], half_extent_m)
        pairs = association.match(found.descriptors, self.descriptors[visible], self._norm) if len(visible) else []
        if pairs:
            seen = np.array([z[i] for i, _ in pairs])
            measured = np.stack([seen[:, 0] * np.cos(seen[:, 1]), seen[:, 0] * np.sin(seen[:, 1])], axis=1)
            predicted = association.to_body(self.landmarks_xy[[visible[row] for _, row in pairs]], self.x[:3])
            agree = association.rigidly_consistent(predicted, measured, CONSENSUS_M)
            pairs = [pair for pair, ok in zip(pairs, agree.tolist()) if ok]
        updated = 0
        for i, row in pairs:
            j = int(visible[row])
            result = slam.update(self.x, self.P, self.head_dim, j, z[i], R[i], self._landmark_gate,
                                 linearize_at=(self._prior_xy, self.first_xy[j]) if self._first_estimates else None)
            updated += int(result.accepted)
        self.counters.landmarks_updated = updated
        return {i for i, _ in pairs}

    def _add_landmarks(self, found: features.Features, z: np.ndarray, R: np.ndarray, matched: set[int], *,
                       cell_m: float) -> None:
        """New landmarks from the thinned keypoints that matched nothing and lie farther than half a
        cell from the map (paper's initialisation, one batch per frame)."""
        room = MAX_LANDMARKS - self.counters.landmarks
        keep = [i for i in features.thin_indices(found.points_px, found.responses, CELL_PX).tolist() if i not in matched]
        if not keep or room <= 0:
            return
        where = features.body_to_world(self.x[:3], z[keep])
        mapped = self.landmarks_xy
        if len(mapped):
            gap = np.min(np.hypot(*(where[:, None, :] - mapped[None, :, :]).transpose(2, 0, 1)), axis=1)
            keep = [i for i, g in zip(keep, gap.tolist()) if g > 0.5 * cell_m]
        keep = keep[:room]
        if not keep:
            return
        self.x, self.P = slam.add_landmarks(self.x, self.P, z[keep], R[keep])
        new = found.descriptors[keep]
        self.descriptors = new.copy() if self.descriptors is None else np.vstack([self.descriptors, new])
        first = self.x[-2 * len(keep):].reshape(-1, 2).copy()
        self.first_xy = first if self.first_xy is None else np.vstack([self.first_xy, first])
        self.counters.landmarks += len(keep)

    def landmark_map(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Landmark positions (m, 2) and their covariances (m, 2, 2); None before the first landmark."""
        count = self.counters.landmarks
        if self.x is None or count == 0:
            return None
        i = self.head_dim + 2 * np.arange(count)
        P = self.P
        cov = np.empty((count, 2, 2))
        cov[:, 0, 0], cov[:, 1, 1] = P[i, i], P[i + 1, i + 1]
        cov[:, 0, 1] = cov[:, 1, 0] = P[i, i + 1]
        return self.landmarks_xy.copy(), cov

    def _reset_position(self, offset_m: np.ndarray, variance_m2: float) -> None:
        super()._reset_position(offset_m, variance_m2)
        self._prior_xy = self.x[:2].copy()  # the jump is not motion

    def _diverged(self) -> bool:
        """Non-finite state, a pose block that is not positive definite, or a map variance <= 0
        (O(n): a full check of P would cost O(n^3) per cycle)."""
        diagonal = np.diagonal(self.P)
        return not (math.isfinite(float(self.x.sum())) and ekf.is_spd4(self.P[:POSE_DIM, :POSE_DIM])
                    and bool(np.all(diagonal > 0)) and math.isfinite(float(diagonal.sum())))

    def _remember_good(self, t_us: int) -> None:
        if t_us >= self._good_until_us:
            super()._remember_good(t_us)
            self._good_until_us = t_us + GOOD_PERIOD_US

    def _inflated(self, P: np.ndarray) -> np.ndarray:
        out = DIVERGENCE_INFLATION * P
        out[:POSE_DIM, :POSE_DIM] += np.diag(DIVERGENCE_FLOOR)
        return out

    def _recover(self, t_us: int) -> None:
        super()._recover(t_us)
        if self.x is not None:  # the fallback's map, and the descriptors of the landmarks it had
            kept = self.counters.landmarks = (len(self.x) - self.head_dim) // 2
            self.descriptors = None if self.descriptors is None else self.descriptors[:kept]
            self.first_xy = None if self.first_xy is None else self.first_xy[:kept]
            self._slot = {ident: j for ident, j in self._slot.items() if j < kept}
            self._slot_of = {}  # slots are handed out afresh: the fallback's states are not theirs
            self._prior_xy = self.x[:2].copy()
        else:
            self.descriptors, self.first_xy, self.counters.landmarks, self._slot = None, None, 0, {}

    def snapshot(self) -> dict:
        state = super().snapshot()
        state["descriptors"] = self.descriptors  # never changed in place: shared, not copied
        state["first_xy"] = self.first_xy
        state["_prior_xy"] = self._prior_xy      # replaced, never changed in place
        state["_good_until_us"] = self._good_until_us
        state["_slot"] = self._slot              # replaced, never changed in place
        state["_slot_of"] = self._slot_of  # likewise
        state["_slot_vars"] = self._slot_vars          # likewise
        state["_last_seen_us"] = self._last_seen_us    # likewise
        return state
