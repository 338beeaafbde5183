"""``known-map``: the default ``ekf`` localizing against a surveyed map of landmarks
(``vehicle.landmarks``, id -> position) from camera range-bearing sightings of them.

Each sighting is one EKF update with the range-bearing model of the vision EKF-SLAM paper,
h = [sqrt(dx^2 + dy^2), atan2(dy, dx) - theta] with (dx, dy) = landmark - position (the landmark a
known constant, so only the pose rows of H), behind a chi-square gate: a misread barcode or an
occluded target fails it and is counted, not fused. Odometry, GNSS and cooperative fixes act as in
``ekf``.

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
from vehicle import ekf_slam_core as slam
from vehicle.ekf import gated_update, gate_threshold
from vehicle.estimators.base import SEVERITY_WARNING, Notice
from vehicle.estimators.ekf import UnicycleEkf

LOST_AFTER = 8                              # sightings in a row failing the gate
RELOCALIZE_SIGMA = np.array([1.0, 1.0, 0.5])  # m, m, rad added to the pose's spread when lost


class KnownMapEkf(UnicycleEkf):
    """EKF over the unicycle state with landmark fixes from a known map: see the module docstring."""

    name = "known-map"

    def __init__(self, *, landmarks: tuple[tuple[int, float, float], ...], **ekf_arguments: Any) -> None:
        super().__init__(**ekf_arguments)
        self._map = {int(ident): np.array([x, y], dtype=float) for ident, x, y in landmarks}
        self._landmark_gate = gate_threshold(2, ekf_arguments["gate_probability"])
        self.counters.landmarks = len(self._map)
        self.sightings_fused = self.sightings_rejected = self.unknown_landmarks = 0
        self._failed_in_a_row: list[int] = []  # landmark ids of the current run of gate failures

    def _landmark_sighting(self, msg: m.LandmarkSighting) -> None:
        """One gated range-bearing update against the mapped landmark."""
        self._propagate_to(msg.stamp_us)
        where = self._map.get(msg.landmark_id)
        if where is None:
            self.unknown_landmarks += 1
            return
        predicted, H_pose, _ = slam.observe(np.concatenate([self.x[:3], where]), 3, 0)
        H = np.zeros((2, self.state_dim))
        H[:, :3] = H_pose
        y = np.array([msg.range_m - predicted[0], wrap_angle(msg.bearing_rad - predicted[1])])
        self.x, self.P, result = gated_update(self.x, self.P, y, H, msg.covariance, self._landmark_gate)
        self.x[2] = wrap_angle(self.x[2])
        if result.accepted:
            self.sightings_fused += 1
            self._failed_in_a_row = []
            return
        self.sightings_rejected += 1
        self._failed_in_a_row.append(msg.landmark_id)
        if len(self._failed_in_a_row) >= LOST_AFTER and len(set(self._failed_in_a_row)) >= 2:
            self._relocalize(msg.stamp_us)

    def _relocalize(self, t_us: int) -> None:
        """Widen the pose's spread so the map can pull it back (see the module docstring)."""
        failed = len(self._failed_in_a_row)
        self._failed_in_a_row = []
        variances = np.diagonal(self.P)[:3] + RELOCALIZE_SIGMA**2
        self.P[:3, :] = 0.0
        self.P[:, :3] = 0.0
        self.P[:3, :3] = np.diag(variances)
        self.counters.resets += 1
        self._notice(Notice(t_us, SEVERITY_WARNING, f"lost track: {failed} landmark sightings in a row failed "
                                                    "the gate; re-localizing against the map"))

    def snapshot(self) -> dict:
        state = super().snapshot()
        state.update(sightings_fused=self.sightings_fused, sightings_rejected=self.sightings_rejected,
                     unknown_landmarks=self.unknown_landmarks, _failed_in_a_row=list(self._failed_in_a_row))
        return state
