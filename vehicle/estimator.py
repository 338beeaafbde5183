"""A vehicle's estimator core: turns decoded sensor messages, in stamp order, into state estimates.

Pure: no bus, no clock. The node feeds it messages and asks for an estimate once per loop cycle.
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass

import numpy as np

from bus import messages as m
from bus.config import SensorSpec
from pymavlink.dialects.v20 import common as mavlink2
from bus.mavlink_codec import EstimatorStatus, StateEstimate
from vehicle import unicycle_ekf as ekf
from vehicle.alignment import GnssAlignment
from vehicle.cooperative import CooperativeFix, cooperative_update
from vehicle.ekf import gate_threshold
from vehicle.gnss_health import GnssHealth, GnssHealthSpec

_GYRO_STALE_PERIODS = 5
_NOT_ESTIMATED_VAR = 1e-6  # z, roll, pitch: constant altitude, level flight
_MUTABLE = ("x", "P", "time_us", "_speed_mps", "_odom_yaw_rate", "_gyro_radps", "_gyro_stamp_us", "counters",
            "gnss_health", "alignment")


@dataclass
class EstimatorCounters:
    gnss_accepted: int = 0
    gnss_rejected: int = 0
    stale: int = 0
    resets: int = 0
    v2v_fused: int = 0
    v2v_rejected: int = 0
    last_gnss_test_ratio: float = 0.0
    last_gnss_mean_test_ratio: float = 0.0


def _copy_state(state: dict) -> dict:
    """Copies of the mutable parts (arrays, counters, health monitor, alignment); scalars are shared."""
    out = dict(state)
    for key in ("x", "P"):
        if out[key] is not None:
            out[key] = out[key].copy()
    out["counters"] = dataclasses.replace(state["counters"])
    out["gnss_health"] = state["gnss_health"].copy()
    out["alignment"] = copy.copy(state["alignment"])
    return out


class VehicleEstimator:
    """EKF over [x, y, theta, gyro_bias] driven by odometry speed and gyro yaw rate, GNSS-corrected."""

    def __init__(self, *, vehicle_id: int, spec: SensorSpec, gate_probability: float, altitude_m: float) -> None:
        self.vehicle_id = vehicle_id
        self._spec = spec
        self._gate = gate_threshold(2, gate_probability)
        self._altitude_m = altitude_m
        self._noise = ekf.InputNoise(spec.odom_speed_sigma_mps, 1.0 / spec.odom_rate_hz, spec.gyro_sigma_radps,
                                     1.0 / spec.imu_rate_hz, spec.gyro_bias_walk_radps_rtsec)
        # when the gyro is silent, yaw rate comes from odometry (its noise and period, no bias)
        self._odom_noise = ekf.InputNoise(spec.odom_speed_sigma_mps, 1.0 / spec.odom_rate_hz,
                                          spec.odom_yaw_rate_sigma_radps, 1.0 / spec.odom_rate_hz,
                                          spec.gyro_bias_walk_radps_rtsec)
        self._gyro_period_us = round(1e6 / spec.imu_rate_hz)
        self.x: np.ndarray | None = None
        self.P: np.ndarray | None = None
        self.time_us = 0
        self._speed_mps = 0.0
        self._odom_yaw_rate = 0.0
        self._gyro_radps = 0.0
        self._gyro_stamp_us: int | None = None
        self.counters = EstimatorCounters()
        self.gnss_health = GnssHealth(GnssHealthSpec(gate_probability=gate_probability))
        self.alignment = GnssAlignment()

    @property
    def initialized(self) -> bool:
        return self.x is not None

    def handle(self, msg: object) -> None:
        """Apply one message; messages must come in non-decreasing stamp order (older ones are counted)."""
        if isinstance(msg, m.PosePrior):
            self._initialise(msg.pose, msg.covariance, msg.stamp_us)
            return
        if self.x is None:
            self._align(msg)
            return
        if msg.stamp_us < self.time_us:
            self.counters.stale += 1
            return
        self.propagate_to(msg.stamp_us)
        if isinstance(msg, m.ImuSample):
            self._gyro_radps, self._gyro_stamp_us = float(msg.gyro_radps[2]), msg.stamp_us
        elif isinstance(msg, m.WheelOdometry):
            self._speed_mps, self._odom_yaw_rate = msg.speed_mps, msg.yaw_rate_radps
        elif isinstance(msg, m.GnssFix):
            self._fuse_gnss(msg)
        elif isinstance(msg, CooperativeFix):
            self.x, self.P, result = cooperative_update(self.x, self.P, msg, self._gate)
            if result.accepted:
                self.counters.v2v_fused += 1
            else:
                self.counters.v2v_rejected += 1

    def _initialise(self, pose: np.ndarray, covariance: np.ndarray, stamp_us: int) -> None:
        """Start the filter at ``pose`` (3,) with covariance (3, 3); the gyro bias from its datasheet spread."""
        self.x = np.append(pose, 0.0)
        self.P = np.zeros((4, 4))
        self.P[:3, :3] = covariance
        self.P[3, 3] = self._spec.gyro_bias_sigma_radps**2
        self.time_us = stamp_us

    def _align(self, msg: object) -> None:
        """No prior (a restart in flight): align from the GNSS track and the gyro (vehicle.alignment)."""
        if isinstance(msg, m.ImuSample):
            self.alignment.yaw_rate(msg.stamp_us, float(msg.gyro_radps[2]))
            self._gyro_radps, self._gyro_stamp_us = float(msg.gyro_radps[2]), msg.stamp_us
        elif isinstance(msg, m.WheelOdometry):
            self._speed_mps, self._odom_yaw_rate = msg.speed_mps, msg.yaw_rate_radps
        elif isinstance(msg, m.GnssFix):
            aligned = self.alignment.fix(msg.stamp_us, msg.position_m, msg.covariance_m2)
            if aligned is not None:
                self._initialise(*aligned, msg.stamp_us)
                self.gnss_health.last_fix_us = msg.stamp_us

    def propagate_to(self, stamp_us: int) -> None:
        """Predict with the held inputs from the current time to ``stamp_us`` (commits the filter)."""
        if self.x is not None and stamp_us > self.time_us:
            self.x, self.P = self.predicted(stamp_us)
            self.time_us = stamp_us

    def predicted(self, stamp_us: int) -> tuple[np.ndarray, np.ndarray]:
        """State (4,) and covariance (4, 4) predicted to ``stamp_us`` without changing the filter."""
        if self.x is None:
            raise RuntimeError("the estimator has not been initialised by a pose prior")
        if stamp_us <= self.time_us:
            return self.x, self.P
        dt = (stamp_us - self.time_us) * 1e-6
        gyro_fresh = (self._gyro_stamp_us is not None
                      and stamp_us - self._gyro_stamp_us <= _GYRO_STALE_PERIODS * self._gyro_period_us)
        if gyro_fresh:
            return ekf.predict(self.x, self.P, self._speed_mps, self._gyro_radps, dt, self._noise)
        return ekf.predict(self.x, self.P, self._speed_mps, self._odom_yaw_rate, dt, self._odom_noise, use_bias=False)

    def _fuse_gnss(self, fix: m.GnssFix) -> None:
        """Fuse a fix only if the GNSS health monitor trusts the receiver and the fix passes its tests."""
        verdict = self.gnss_health.check(fix.stamp_us, fix.position_m - self.x[:2], self.P[:2, :2] + fix.covariance_m2,
                                         fix.covariance_m2)
        self.counters.last_gnss_test_ratio = verdict.test_ratio
        self.counters.last_gnss_mean_test_ratio = verdict.mean_test_ratio
        if verdict.reset_offset_m is not None:
            self._reset_position(verdict.reset_offset_m, verdict.reset_variance_m2)
        if not verdict.fuse:
            self.counters.gnss_rejected += 1
            return
        self.x, self.P, _ = ekf.gnss_update(self.x, self.P, fix.position_m, fix.covariance_m2, self._gate)
        self.counters.gnss_accepted += 1

    def _reset_position(self, offset_m: np.ndarray, variance_m2: float) -> None:
        """Jump the position by ``offset_m`` (2,) with per-axis variance ``variance_m2``; decorrelate it."""
        self.x[:2] += offset_m
        self.P[:2, 2:] = 0.0
        self.P[2:, :2] = 0.0
        self.P[:2, :2] = np.eye(2) * variance_m2
        self.counters.resets += 1

    def tick(self, stamp_us: int) -> None:
        """Once per loop cycle: notices loss of GNSS fix."""
        self.gnss_health.tick(stamp_us)

    def diverged(self) -> bool:
        """Non-finite state or covariance, or a covariance that is no longer positive definite."""
        if self.x is None:
            return False
        if not (np.all(np.isfinite(self.x)) and np.all(np.isfinite(self.P))):
            return True
        return bool(np.any(np.linalg.eigvalsh(self.P) <= 0.0))

    def snapshot(self) -> dict:
        """A copy of everything that changes as measurements are fused (for the fusion horizon)."""
        return _copy_state({k: self.__dict__[k] for k in _MUTABLE})

    def restore(self, snapshot: dict) -> None:
        """Go back to a :meth:`snapshot` (health transitions already reported are not replayed)."""
        transitions = self.gnss_health.transitions
        self.__dict__.update(_copy_state(snapshot))
        self.gnss_health.transitions = transitions

    def reset_from(self, x: np.ndarray, P: np.ndarray) -> None:
        """Divergence guard: restart the filter from a last good state (4,) with covariance (4, 4)."""
        self.x, self.P = x.copy(), P.copy()
        self.counters.resets += 1

    def status(self, stamp_us: int) -> EstimatorStatus:
        """ESTIMATOR_STATUS contents: GPS glitch flag while GNSS is distrusted, the larger GNSS test ratio."""
        flags = mavlink2.ESTIMATOR_ATTITUDE | mavlink2.ESTIMATOR_VELOCITY_HORIZ | mavlink2.ESTIMATOR_POS_HORIZ_REL
        flags |= mavlink2.ESTIMATOR_POS_HORIZ_ABS if self.gnss_health.healthy else mavlink2.ESTIMATOR_GPS_GLITCH
        c = self.counters
        _, P = self.predicted(stamp_us)
        return EstimatorStatus(self.vehicle_id, stamp_us, flags, max(c.last_gnss_test_ratio, c.last_gnss_mean_test_ratio),
                               float(np.sqrt(0.5 * (P[0, 0] + P[1, 1]))))

    def estimate(self, stamp_us: int, reset_counter: int = 0) -> StateEstimate:
        """The estimate predicted to ``stamp_us`` as a StateEstimate (NED, body-frame velocity)."""
        x, P = self.predicted(stamp_us)
        pose_cov = np.diag([0.0, 0.0, _NOT_ESTIMATED_VAR, _NOT_ESTIMATED_VAR, _NOT_ESTIMATED_VAR, 0.0])
        index = np.array([0, 1, 5])
        pose_cov[np.ix_(index, index)] = P[:3, :3]
        yaw_rate_var = self._spec.gyro_sigma_radps**2 + P[3, 3]
        vel_cov = np.diag([self._spec.odom_speed_sigma_mps**2, _NOT_ESTIMATED_VAR, _NOT_ESTIMATED_VAR,
                           _NOT_ESTIMATED_VAR, _NOT_ESTIMATED_VAR, yaw_rate_var])
        return StateEstimate(
            vehicle_id=self.vehicle_id, time_usec=max(stamp_us, self.time_us),
            position_m=np.array([x[0], x[1], -self._altitude_m]), yaw_rad=float(x[2]),
            velocity_mps=np.array([self._speed_mps, 0.0, 0.0]), yaw_rate_radps=self._gyro_radps - float(x[3]),
            pose_covariance=pose_cov, velocity_covariance=vel_cov, reset_counter=reset_counter,
        )
