"""The centralized reference of the cooperative paper: one EKF over every vehicle's state, fed every
vehicle's inputs, GNSS fixes and vehicle-to-vehicle ranging, with the exact cross-covariances that
decentralized filters cannot keep (so no Covariance Intersection is needed: nothing is counted
twice). It is the accuracy yardstick of the decentralized variants, not a vehicle: it runs in one
process next to the pure world (``swarm experiment cooperative``).

Joint state X = [x_1 ... x_N], each block x_i the state of one vehicle's filter (vehicle.estimators,
built with a ``JointBlock`` store: its own models, its x and P a block of the joint state) (``ekf``:
[x, y, theta, gyro_bias], grown by the two GNSS error states when the datasheet has a correlated
GNSS error (vehicle.models.gnss_error); ``known-map``: also its odometry and camera range scale states and
the range-error states of the landmarks in view, so a block grows and shrinks). Each block keeps its vehicle
estimator's own models and book-keeping (the same held inputs, F and Q, sighting model, gate and
re-localization), and their effect lands on the joint covariance: a motion step P[i, :] <- F_i P[i, :],
P[:, i] <- P[:, i] F_i^T, P[i, i] += Q_i; an update by H over block i with the joint gain, so the
other blocks move through their cross-covariances; added states uncorrelated, dropped states
marginalized. Blocks may stand at different times: process noise is independent between vehicles,
so the joint covariance stays exact as long as every block a measurement involves is first
propagated to its stamp. GNSS observes [x_i, y_i] as on the vehicle (position plus error states, the
white part of the noise); ranging observes the range and bearing of j seen from i (paper eq. 4.1),
H = [dh/dx_i, dh/dp_j] on both blocks. Every update is behind the vehicles' chi-square gate.

Pure: no bus, no clock.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from bus.config import SensorSpec
from bus.statistics import gate_threshold
from vehicle.estimators import ekf
from vehicle.estimators.filter import Filter
from vehicle.estimators.state import FilterState
from vehicle.models import added_states
from vehicle.models.cooperative import Correction
from vehicle.models.cooperative_fixes import relative_model
from vehicle.models.kalman import UpdateResult, gated_update


class JointBlock:
    """The store of one vehicle's filter inside a :class:`CentralizedEkf` (vehicle.estimators.stores):
    its motion steps, updates, added or dropped states and spread resets act on the joint state,
    cross-covariances included; the filter's own x and P are the block's, refreshed after each."""

    dense = False  # the filter's x and P are copies of the block: the closed-form prediction cannot replace them

    def __init__(self, joint: CentralizedEkf, vehicle_id: int) -> None:
        self.joint, self.vehicle_id = joint, vehicle_id

    def move(self, s: FilterState, F: np.ndarray, Q: np.ndarray, x_next: np.ndarray) -> None:
        s.P = self.joint.move_block(self.vehicle_id, F, Q)
        s.x = x_next

    def update(
        self, s: FilterState, y: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float, idx: list[int] | None = None
    ) -> UpdateResult:
        if idx is not None:
            full = np.zeros((len(y), len(s.x)))
            full[:, idx] = H
            H = full
        return self.joint.update_block(self.vehicle_id, y, H, R, gate)

    def correct(self, s: FilterState, correction: Correction) -> None:
        raise NotImplementedError("the centralized reference fuses ranging on the joint state itself")

    def append(self, s: FilterState, variances: np.ndarray) -> None:
        self.joint.grow_block(self.vehicle_id, variances)

    def drop(self, s: FilterState, indices: list[int]) -> None:
        self.joint.shrink_block(self.vehicle_id, indices)

    def set_spread(self, s: FilterState, indices: list[int], variances: np.ndarray) -> None:
        self.joint.spread_block(self.vehicle_id, indices, variances)

    def inflate(self, s: FilterState, indices: list[int], variances: np.ndarray) -> None:
        self.joint.inflate_block(self.vehicle_id, indices, variances)


class CentralizedEkf:
    """EKF over every vehicle of ``vehicle_ids`` (module docstring). Feed it every vehicle's samples
    in stamp order (``handle``) and call ``cycle(t_us)`` once per loop period. ``estimator`` builds
    each vehicle's filter (an estimator module's ``build``: ``ekf``'s, or ``known_map``'s with its
    ``landmarks`` among ``estimator_arguments``)."""

    def __init__(
        self,
        vehicle_ids: list[int],
        *,
        spec: SensorSpec,
        gate_probability: float,
        estimator: Callable[..., Filter] = ekf.build,
        **estimator_arguments: Any,
    ) -> None:
        self.vehicle_ids = list(vehicle_ids)
        self._vehicles = {
            vid: estimator(
                vehicle_id=vid,
                spec=spec,
                gate_probability=gate_probability,
                store=JointBlock(self, vid),
                **estimator_arguments,
            )
            for vid in self.vehicle_ids
        }
        self._dims = {vid: 0 for vid in self.vehicle_ids}  # each block's size; 0 before its prior
        self.x = np.zeros(0)
        self.P = np.zeros((0, 0))
        self._gate = gate_threshold(2, gate_probability)
        self.accepted, self.rejected = 0, 0

    def block(self, vehicle_id: int) -> slice:
        start = 0
        for vid in self.vehicle_ids:
            if vid == vehicle_id:
                return slice(start, start + self._dims[vid])
            start += self._dims[vid]
        raise KeyError(vehicle_id)

    @property
    def initialized(self) -> bool:
        return all(v.initialized for v in self._vehicles.values())

    def pose(self, vehicle_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Pose estimate (3,) [m, m, rad] and its covariance (3, 3) of one vehicle."""
        s = self.block(vehicle_id)
        return self.x[s][:3].copy(), self.P[s, s][:3, :3].copy()

    def poses_covariance(self) -> np.ndarray:
        """The joint covariance (3N, 3N) of every vehicle's pose [x, y, theta], vehicles in
        ``vehicle_ids`` order, cross-covariances included."""
        at = np.concatenate([np.arange(self.block(vid).start, self.block(vid).start + 3) for vid in self.vehicle_ids])
        return self.P[np.ix_(at, at)].copy()

    def handle(self, msg: Any) -> None:
        """One sample of any vehicle; unknown vehicles, and a vehicle's samples before its prior, are ignored."""
        vehicle = self._vehicles.get(msg.vehicle_id)
        if vehicle is None:
            return
        if isinstance(msg, m.PosePrior):
            vehicle.handle(msg)
            self._replace_block(msg.vehicle_id, vehicle.state.x, vehicle.state.P)
        elif not vehicle.initialized or isinstance(msg, m.SeenBy):  # a relay: the observer's own sighting counts
            return
        elif isinstance(msg, m.GnssFix):
            self._propagate(msg.vehicle_id, msg.stamp_us)
            self._gnss_update(msg)
        elif isinstance(msg, m.RangeBearing):
            target = self._vehicles.get(msg.target_id)
            if target is not None and target.initialized and target is not vehicle:
                self._propagate(msg.vehicle_id, msg.stamp_us)
                self._propagate(msg.target_id, msg.stamp_us)
                self._ranging_update(msg)
        else:  # inputs, and what the vehicle's own filter models (landmark sightings)
            vehicle.handle(msg)
            self._pull(msg.vehicle_id)

    def cycle(self, t_us: int) -> None:
        """Propagate every vehicle (that has its prior) to ``t_us``."""
        for vid, vehicle in self._vehicles.items():
            if vehicle.initialized:
                self._propagate(vid, t_us)

    def _propagate(self, vehicle_id: int, t_us: int) -> None:
        self._vehicles[vehicle_id].propagate_to(t_us)
        self._pull(vehicle_id)

    def _pull(self, vehicle_id: int) -> None:
        """The block's mean from its vehicle's filter (which moves it between joint operations)."""
        self.x[self.block(vehicle_id)] = self._vehicles[vehicle_id].state.x

    def _push(self, vehicle_id: int) -> None:
        """The block's mean and covariance back to its vehicle's filter."""
        s, state = self.block(vehicle_id), self._vehicles[vehicle_id].state
        state.x, state.P = self.x[s].copy(), self.P[s, s].copy()

    def _replace_block(self, vehicle_id: int, x: np.ndarray, P: np.ndarray) -> None:
        """A fresh block (a prior): uncorrelated with every other."""
        s = self.block(vehicle_id)
        self.x, self.P = added_states.drop_states(self.x, self.P, list(range(s.start, s.stop)))
        self.x, self.P = added_states.insert_states(self.x, self.P, s.start, x, P)
        self._dims[vehicle_id] = len(x)
        self._push(vehicle_id)

    def move_block(self, vehicle_id: int, F: np.ndarray, Q: np.ndarray) -> np.ndarray:
        """One motion step of a block: P[i, :] <- F P[i, :], P[:, i] <- P[:, i] F^T, P[i, i] += Q;
        returns the block's new covariance (a copy)."""
        s = self.block(vehicle_id)
        self.P[s, :] = F @ self.P[s, :]
        self.P[:, s] = self.P[:, s] @ F.T
        self.P[s, s] += Q
        self.P[s, s] = 0.5 * (self.P[s, s] + self.P[s, s].T)
        return self.P[s, s].copy()

    def grow_block(self, vehicle_id: int, variances: np.ndarray) -> None:
        """States at 0 with these variances after the block's last, uncorrelated."""
        self._pull(vehicle_id)
        at = self.block(vehicle_id).stop
        self.x, self.P = added_states.insert_states(self.x, self.P, at, np.zeros(len(variances)), np.diag(variances))
        self._dims[vehicle_id] += len(variances)
        self._push(vehicle_id)

    def shrink_block(self, vehicle_id: int, indices: list[int]) -> None:
        """The block's states at ``indices`` (within the block) marginalized out."""
        self._pull(vehicle_id)
        s = self.block(vehicle_id)
        self.x, self.P = added_states.drop_states(self.x, self.P, [s.start + i for i in indices])
        self._dims[vehicle_id] -= len(indices)
        self._push(vehicle_id)

    def spread_block(self, vehicle_id: int, indices: list[int], variances: np.ndarray) -> None:
        """The block's states at ``indices`` uncorrelated with every joint state, with these variances."""
        added_states.set_spread(self.P, [self.block(vehicle_id).start + i for i in indices], variances)
        self._push(vehicle_id)

    def inflate_block(self, vehicle_id: int, indices: list[int], variances: np.ndarray) -> None:
        """The block's states at ``indices`` get these variances added (process noise)."""
        at = [self.block(vehicle_id).start + i for i in indices]
        self.P[at, at] += variances
        self._push(vehicle_id)

    def update_block(
        self, vehicle_id: int, y: np.ndarray, H_block: np.ndarray, R: np.ndarray, gate: float
    ) -> UpdateResult:
        """A vehicle filter's own update (H over its block) on the joint state."""
        self._pull(vehicle_id)
        s = self.block(vehicle_id)
        H = np.zeros((len(y), len(self.x)))
        H[:, s] = H_block
        return self._update(y, H, R, gate)

    def _gnss_update(self, fix: m.GnssFix) -> None:
        """A fix on one block, modelled as the vehicle models it."""
        vehicle = self._vehicles[fix.vehicle_id]
        observed = vehicle.gnss.observe(vehicle.state.x, fix.covariance_m2)
        H = observed.full_H(len(vehicle.state.x))
        self.update_block(fix.vehicle_id, fix.position_m - observed.predicted, H, observed.R, self._gate)

    def _ranging_update(self, msg: m.RangeBearing) -> None:
        """Range and bearing of ``target_id`` seen from ``vehicle_id`` (paper eq. 4.1) on both blocks."""
        si, sj = self.block(msg.vehicle_id), self.block(msg.target_id)
        predicted, H_i, H_j = relative_model(self.x[si], self.x[sj][:2])
        H = np.zeros((2, len(self.x)))
        H[:, si] = H_i
        H[:, sj.start : sj.start + 2] = H_j
        y = np.array([msg.range_m - predicted[0], wrap_angle(msg.bearing_rad - predicted[1])])
        self._update(y, H, msg.covariance, self._gate)

    def _update(self, y: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float) -> UpdateResult:
        """A joint gated update; every block moves (through its cross-covariances), so all are pushed."""
        self.x, self.P, result = gated_update(self.x, self.P, y, H, R, gate)
        for vid in self.vehicle_ids:
            if self._dims[vid]:
                heading = self.block(vid).start + 2
                self.x[heading] = wrap_angle(self.x[heading])
                self._push(vid)
        self.accepted += int(result.accepted)
        self.rejected += int(not result.accepted)
        return result
