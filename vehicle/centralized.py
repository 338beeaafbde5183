"""The centralized reference of the cooperative paper: one EKF over every vehicle's state, fed every
vehicle's inputs, GNSS fixes and vehicle-to-vehicle ranging, with the exact cross-covariances that
decentralized filters cannot keep (so no Covariance Intersection is needed: nothing is counted
twice). It is the accuracy yardstick of the decentralized variants, not a vehicle: it runs in one
process next to the pure world (``swarm experiment cooperative``).

Joint state X = [x_1 ... x_N] with x_i = [x, y, theta, gyro_bias] (4N,), each block grown by the
two GNSS error states when the datasheet has a correlated GNSS error (vehicle.gnss_error; 6N). Each vehicle's motion is the
vehicle EKF's own (``vehicle.unicycle_ekf``: the same held inputs, the same F and Q), applied to its
block of P and to its cross-covariances: P[i, :] <- F_i P[i, :], P[:, i] <- P[:, i] F_i^T, P[i, i] += Q_i.
Blocks may stand at different times: process noise is independent between vehicles, so the joint
covariance stays exact as long as every block a measurement involves is first propagated to its
stamp. GNSS observes [x_i, y_i]; ranging observes the range and bearing of j seen from i (paper eq.
4.1), H = [dh/dx_i, dh/dp_j] on both blocks.
GNSS fixes are modelled as on the vehicle (position plus error states, the white part of the noise). Every update is behind the vehicles' chi-square gate.

Pure: no bus, no clock.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from bus.config import SensorSpec
from vehicle.cooperative import relative_model
from vehicle.ekf import UpdateResult, gate_threshold, gated_update
from vehicle.estimators.ekf import UnicycleEkf


class _VehicleMotion(UnicycleEkf):
    """One vehicle's inputs (held and integrated exactly as on the vehicle); its prediction moves
    the mean and leaves F and Q for the joint covariance instead of a private one."""

    motion: tuple[np.ndarray, np.ndarray] | None = None

    def _predict(self, speed: float, rate: float, dt: float, **noise: Any) -> None:
        self.x, F, Q = self._motion(speed, rate, dt, **noise)
        self.motion = (F, Q)


class CentralizedEkf:
    """EKF over every vehicle of ``vehicle_ids`` (module docstring). Feed it every vehicle's samples
    in stamp order (``handle``) and call ``cycle(t_us)`` once per loop period."""

    def __init__(self, vehicle_ids: list[int], *, spec: SensorSpec, gate_probability: float) -> None:
        self.vehicle_ids = list(vehicle_ids)
        self._index = {vid: k for k, vid in enumerate(self.vehicle_ids)}
        self._motion = {vid: _VehicleMotion(vehicle_id=vid, spec=spec, gate_probability=gate_probability,
                                            altitude_m=0.0) for vid in self.vehicle_ids}
        self._block_dim = next(iter(self._motion.values())).state_dim if self._motion else 4
        n = self._block_dim * len(self.vehicle_ids)
        self.x = np.zeros(n)
        self.P = np.zeros((n, n))
        self._gate = gate_threshold(2, gate_probability)
        self.accepted, self.rejected = 0, 0

    def block(self, vehicle_id: int) -> slice:
        k = self._index[vehicle_id]
        return slice(self._block_dim * k, self._block_dim * (k + 1))

    @property
    def initialized(self) -> bool:
        return all(v.initialized for v in self._motion.values())

    def pose(self, vehicle_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Pose estimate (3,) [m, m, rad] and its covariance (3, 3) of one vehicle."""
        s = self.block(vehicle_id)
        return self.x[s][:3].copy(), self.P[s, s][:3, :3].copy()

    def handle(self, topic: str, msg: Any) -> None:
        """One sample of any vehicle; unknown vehicles, and anything before every prior, are ignored."""
        motion = self._motion.get(msg.vehicle_id)
        if motion is None:
            return
        if isinstance(msg, m.PosePrior):
            motion.handle(topic, msg)
            s = self.block(msg.vehicle_id)
            self.x[s], self.P[s, :], self.P[:, s] = motion.x, 0.0, 0.0
            self.P[s, s] = motion.P
        elif not self.initialized:
            return
        elif isinstance(msg, (m.ImuSample, m.WheelOdometry)):
            motion.handle(topic, msg)
        elif isinstance(msg, m.GnssFix):
            self._propagate(msg.vehicle_id, msg.stamp_us)
            self._gnss_update(msg)
        elif isinstance(msg, m.RangeBearing) and msg.target_id in self._index and msg.target_id != msg.vehicle_id:
            self._propagate(msg.vehicle_id, msg.stamp_us)
            self._propagate(msg.target_id, msg.stamp_us)
            self._ranging_update(msg)

    def cycle(self, t_us: int) -> None:
        """Propagate every vehicle to ``t_us``."""
        if self.initialized:
            for vid in self.vehicle_ids:
                self._propagate(vid, t_us)

    def _propagate(self, vehicle_id: int, t_us: int) -> None:
        motion, s = self._motion[vehicle_id], self.block(vehicle_id)
        motion.x, motion.motion = self.x[s].copy(), None
        motion._propagate_to(t_us)
        if motion.motion is None:
            return
        F, Q = motion.motion
        self.x[s] = motion.x
        self.P[s, :] = F @ self.P[s, :]
        self.P[:, s] = self.P[:, s] @ F.T
        self.P[s, s] += Q

    def _gnss_update(self, fix: m.GnssFix) -> None:
        """A fix on one block, modelled as the vehicle models it."""
        motion, s = self._motion[fix.vehicle_id], self.block(fix.vehicle_id)
        motion.x = self.x[s]
        predicted, H_block, R = motion.gnss_model(fix.covariance_m2)
        H = np.zeros((2, len(self.x)))
        H[:, s] = H_block
        self._update(fix.position_m - predicted, H, R)

    def _ranging_update(self, msg: m.RangeBearing) -> None:
        """Range and bearing of ``target_id`` seen from ``vehicle_id`` (paper eq. 4.1) on both blocks."""
        si, sj = self.block(msg.vehicle_id), self.block(msg.target_id)
        predicted, H_i, H_j = relative_model(self.x[si], self.x[sj][:2])
        H = np.zeros((2, len(self.x)))
        H[:, si] = H_i
        H[:, sj.start:sj.start + 2] = H_j
        y = np.array([msg.range_m - predicted[0], wrap_angle(msg.bearing_rad - predicted[1])])
        self._update(y, H, msg.covariance)

    def _update(self, y: np.ndarray, H: np.ndarray, R: np.ndarray) -> UpdateResult:
        self.x, self.P, result = gated_update(self.x, self.P, y, H, R, self._gate)
        heading = self.x[2::self._block_dim]
        self.x[2::self._block_dim] = (heading + np.pi) % (2.0 * np.pi) - np.pi
        self.accepted += int(result.accepted)
        self.rejected += int(not result.accepted)
        return result
