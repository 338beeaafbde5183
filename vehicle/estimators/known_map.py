"""``known-map``: the default ``ekf`` localizing against a surveyed map of landmarks
(``vehicle.landmarks``, id -> position) from camera range-bearing sightings of them.

Each sighting is one EKF update with the range-bearing model of the vision EKF-SLAM paper,
h = [sqrt(dx^2 + dy^2), atan2(dy, dx) - theta] with (dx, dy) = landmark - position (the landmark a
known constant, so only the pose rows of H), behind a chi-square gate: a misread barcode or an
occluded target fails it and is counted, not fused. Odometry, GNSS and cooperative fixes act as in
``ekf``.

Errors that persist (``vehicle.added_states``), each on when its datasheet field is nonzero: the
wheel odometry's speed and yaw-rate scale errors (two states after the base ones, prior sigma
``odom_scale_prior_sigma``, a slow random walk), the camera's range scale (one state after them,
prior sigma ``range_scale_prior_sigma``, the same walk: a camera that reads range from a target's
size in the image reads every target a few per cent long or short), and the camera's
time-correlated range error, one Gauss-Markov state per landmark in view (sigma
``range_correlated_sigma_per_m`` of the range, correlation time ``range_correlation_s``): a camera
that reads a landmark 3 % long reads it 3 % long for seconds, and fusing five such sightings a
second as independent would make the filter sure of a biased pose. That part is taken out of each
sighting's reported range variance (the rest is white). Likewise the bearing's persisting part, a second Gauss-Markov state per landmark in view (a fraction
``bearing_correlated_fraction`` of the sighting's reported bearing variance, correlation time
``bearing_correlation_s``). A landmark's states are dropped (marginalized) when it has not been seen
for ``FORGET_AFTER`` correlation times: by then they are uncorrelated with what a new sighting would read.
A robot sighting (cooperative, ``vehicle.cooperative``) is the same camera's: its errors get the same
states, one set per robot seen and one per robot that sees this one.

Losing track and finding it again: when ``LOST_AFTER`` sightings in a row of at least two different
landmarks all fail the gate, the pose is no longer where the filter believes; its covariance is
widened by ``RELOCALIZE_SIGMA`` (position and heading, cross terms dropped) so the next sightings
pass the gate and pull it back onto the map, and a notice says so.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from vehicle import added_states
from vehicle import ekf_slam_core as slam
from vehicle.ekf import gate_threshold
from vehicle.estimators.base import SEVERITY_WARNING, Notice
from vehicle.estimators.ekf import UnicycleEkf
from vehicle.estimators.sighting_errors import SightingErrors, Subject

LOST_AFTER = 8                              # sightings in a row failing the gate
RELOCALIZE_SIGMA = np.array([1.0, 1.0, 0.5])  # m, m, rad added to the pose's spread when lost
FORGET_AFTER = 5.0           # correlation times unseen before a landmark's range-error state is dropped


class KnownMapEkf(SightingErrors, UnicycleEkf):
    """EKF over the unicycle state with landmark fixes from a known map: see the module docstring."""

    name = "known-map"

    def __init__(self, *, landmarks: tuple[tuple[int, float, float], ...], **ekf_arguments: Any) -> None:
        super().__init__(**ekf_arguments)
        self._map = {int(ident): np.array([x, y], dtype=float) for ident, x, y in landmarks}
        self._landmark_gate = gate_threshold(2, ekf_arguments["gate_probability"])
        self.counters.landmarks = len(self._map)
        self.sightings_fused = self.sightings_rejected = self.unknown_landmarks = 0
        self._failed_in_a_row: list[int] = []  # landmark ids of the current run of gate failures
        spec = self._spec
        self._scale_sigma = spec.odom_scale_prior_sigma
        self._init_sighting_errors(spec)
        self._range_scale_sigma = spec.range_scale_prior_sigma
        after_wheels = self.base_dim + (2 if self._scale_sigma else 0)
        self._range_scale = after_wheels if self._range_scale_sigma else None
        self._first_error_state = after_wheels + (1 if self._range_scale_sigma else 0)
        self.state_dim = self._first_error_state
        self._error_states: dict[Subject, int] = {}  # sighted subject -> index of its first error state
        self._last_seen_us: dict[Subject, int] = {}
        self._decaying: list[tuple[float, float]] = []  # (tau s, stationary variance) of each error state, in order

    def _initialise(self, pose: np.ndarray, covariance: np.ndarray, stamp_us: int, *, from_fixes: bool = False) -> None:
        super()._initialise(pose, covariance, stamp_us, from_fixes=from_fixes)
        self._error_states, self._last_seen_us, self._decaying = {}, {}, []
        if self._scale_sigma:
            self.x, self.P = added_states.append_states(self.x, self.P, np.full(2, self._scale_sigma**2))
        if self._range_scale_sigma:
            self.x, self.P = added_states.append_states(self.x, self.P, np.array([self._range_scale_sigma**2]))
        self.state_dim = len(self.x)

    def _predict(self, speed: float, rate: float, dt: float, **noise: Any) -> None:
        """The motion step with the odometry scale states (when estimated) and the range-error
        states' decay; the base filter's own step when there are neither."""
        if len(self.x) == self.base_dim:
            super()._predict(speed, rate, dt, **noise)
            return
        b, coupling = self.base_dim, None
        if self._scale_sigma:  # a fresh gyro's rate is not the wheels'
            speed, rate, noise, coupling = added_states.scaled_inputs(self.x, b, speed, rate, dt, noise,
                                                                      wheel_rate=not noise.get("use_bias"))
        if self._range_scale_sigma:  # a random walk like the wheels' scales; the motion does not depend on it
            coupling = added_states.with_unused_scale(coupling, b)
        head, F, Q = self._motion(speed, rate, dt, **noise)
        taus, variances = (np.array([d[i] for d in self._decaying]) for i in (0, 1))
        decay, decay_var = added_states.decays(dt, taus, variances)
        walk_var = added_states.SCALE_WALK_PER_RTSEC**2 * dt
        self._apply_motion(*added_states.transition(len(self.x), F, Q, coupling, walk_var, decay, decay_var,
                                                    self._first_error_state))
        tail = self.x[b:].copy()
        tail[self._first_error_state - b:] *= decay
        self.x = np.concatenate([head, tail])

    def _landmark_sighting(self, msg: m.LandmarkSighting) -> None:
        """One gated range-bearing update against the mapped landmark."""
        self._propagate_to(msg.stamp_us)
        where = self._map.get(msg.landmark_id)
        if where is None:
            self.unknown_landmarks += 1
            return
        R = np.array(msg.covariance, dtype=float)
        model = self._error_model(self._error_index(("landmark", msg.landmark_id), msg.stamp_us, R[1, 1])) \
            if self._per_subject else {}
        if self._range_scale is not None:
            model["scale_state"] = self._range_scale
        predicted, H_pose, _ = slam.observe(np.concatenate([self.x[:3], where]), 3, 0)
        H = np.zeros((2, len(self.x)))
        H[:, :3] = H_pose
        if model:  # range r (1 + k + s_l), bearing beta + b_l, each + white (vehicle.added_states)
            H, R, predicted = added_states.persisting_sighting(H, R, predicted, self.x, **model)
        y = np.array([msg.range_m - predicted[0], wrap_angle(msg.bearing_rad - predicted[1])])
        result = self._fuse(y, H, R, self._landmark_gate)
        if result.accepted:
            self.sightings_fused += 1
            self._failed_in_a_row = []
            return
        self.sightings_rejected += 1
        self._failed_in_a_row.append(msg.landmark_id)
        if len(self._failed_in_a_row) >= LOST_AFTER and len(set(self._failed_in_a_row)) >= 2:
            self._relocalize(msg.stamp_us)

    def _stationary_variance(self, index: int) -> float:
        return self._decaying[index - self._first_error_state][1]

    def _error_index(self, key: Subject, t_us: int, bearing_var: float) -> int:
        """The index of the first error state (range, then bearing) of the sighted subject ``key`` (a
        landmark, a robot seen, a robot seeing this one), added (at 0, stationary variance: the
        bearing's a fraction of ``bearing_var``, the sighting's reported one) when it has none; states
        of subjects unseen for FORGET_AFTER correlation times are dropped first."""
        self._last_seen_us[key] = t_us
        if key in self._error_states:
            return self._error_states[key]
        horizon_us = FORGET_AFTER * max(self._range_tau, self._bearing_tau) * 1e6
        stale = [ident for ident in self._error_states if t_us - self._last_seen_us[ident] > horizon_us]
        per = self._per_subject
        if stale:
            dropped = [self._error_states[i] + k for i in stale for k in range(per)]
            self._drop_states(dropped)
            first = self._first_error_state
            self._decaying = [d for i, d in enumerate(self._decaying) if first + i not in dropped]
            kept = sorted((index, ident) for ident, index in self._error_states.items() if ident not in stale)
            self._error_states = {ident: first + per * k for k, (_, ident) in enumerate(kept)}
            for ident in stale:
                del self._last_seen_us[ident]
        self._error_states[key] = len(self.x)
        new = self._subject_states(bearing_var)
        self._decaying = self._decaying + new
        self._append_states(np.array([variance for _, variance in new]))
        return self._error_states[key]

    def _append_states(self, variances: np.ndarray) -> None:
        """States at 0 with these variances after the last one (added_states.append_states)."""
        self.x, self.P = added_states.append_states(self.x, self.P, variances)
        self.state_dim = len(self.x)

    def _drop_states(self, indices: list[int]) -> None:
        """The states at ``indices`` marginalized out (added_states.drop_states)."""
        self.x, self.P = added_states.drop_states(self.x, self.P, indices)
        self.state_dim = len(self.x)

    def _relocalize(self, t_us: int) -> None:
        """Widen the pose's spread so the map can pull it back (see the module docstring)."""
        failed = len(self._failed_in_a_row)
        self._failed_in_a_row = []
        self._set_spread([0, 1, 2], np.diagonal(self.P)[:3] + RELOCALIZE_SIGMA**2)
        self.counters.resets += 1
        self._notice(Notice(t_us, SEVERITY_WARNING, f"lost track: {failed} landmark sightings in a row failed "
                                                    "the gate; re-localizing against the map"))

    def snapshot(self) -> dict:
        state = super().snapshot()
        state.update(sightings_fused=self.sightings_fused, sightings_rejected=self.sightings_rejected,
                     unknown_landmarks=self.unknown_landmarks, _failed_in_a_row=list(self._failed_in_a_row),
                     _error_states=dict(self._error_states), _last_seen_us=dict(self._last_seen_us),
                     _decaying=list(self._decaying),
                     state_dim=self.state_dim)
        return state
