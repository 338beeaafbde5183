"""``ekf``: the default vehicle estimator, an EKF over [x, y, theta, gyro_bias] driven by odometry speed
and gyro yaw rate (integrated between cycles: one prediction per loop cycle), GNSS-corrected behind
the GNSS health monitor, with cooperative (Covariance Intersection) updates from neighbours. When the
datasheet gives a time-correlated part of the GNSS error (``gnss_correlated_sigma_m``), the state
grows by that error's two Gauss-Markov states (vehicle.gnss_error), [..., e_x, e_y] (6,).

Pure: no bus, no clock.
"""

from __future__ import annotations

import dataclasses
import math
from functools import partial
from typing import Any

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from bus import messages as m
from bus.angles import wrap_angle
from bus.config import SensorSpec
from bus.mavlink_codec import EstimatorStatus, StateEstimate
from vehicle import added_states
from vehicle import unicycle_ekf as ekf
from vehicle.adaptive import NoiseAdaptation
from vehicle.alignment import GnssAlignment
from vehicle.cooperative import CooperativeFix, CooperativeRule, Correction, SeenFix, apply_correction
from vehicle.gnss_error import GnssErrorModel, aligned_covariance, augment_motion, observation
from vehicle.ekf import UpdateResult, gate_threshold, gated_update
from vehicle.estimators.base import SEVERITY_INFO, SEVERITY_WARNING, EstimatorCounters, Notice
from vehicle.gnss_health import GnssHealth, GnssHealthSpec
from vehicle.inputs import HeldInput, swept
from vehicle.shallow import shallow_copy
from vehicle.wheel_slip import SlipGuard

GYRO_STALE_PERIODS = 5
NOT_ESTIMATED_VAR = 1e-6  # z, roll, pitch: constant altitude, level flight
DIVERGENCE_INFLATION = 10.0
DIVERGENCE_FLOOR = np.array([1.0, 1.0, 0.01, 1e-4])  # m^2, m^2, rad^2, (rad/s)^2
_MUTABLE = ("x", "P", "time_us", "speed", "gyro", "odom_yaw", "counters", "gnss_health", "alignment", "_last_good", "iae", "slip")


class UnicycleEkf:
    """EKF over [x, y, theta, gyro_bias] (4,): see the module docstring."""

    name = "ekf"
    unscented_fixes = False  # range and bearing of cooperative fixes through sigma points (ukf)
    models_gnss_error = True  # estimate the datasheet's correlated GNSS error (ekf-slam does not)
    fast_predict = True  # ekf.predict_fast without GNSS error states; off: F and Q through _apply_motion

    def __init__(self, *, vehicle_id: int, spec: SensorSpec, gate_probability: float, altitude_m: float,
                 cooperative: CooperativeRule = CooperativeRule(), adaptive_window: int = 0) -> None:
        self.vehicle_id, self._spec, self._altitude_m = vehicle_id, spec, altitude_m
        self._rule = cooperative
        self._gnss_error = GnssErrorModel.from_spec(spec) if self.models_gnss_error else None
        self.base_dim = 4 if self._gnss_error is None else 6  # what this class's own models cover
        self.state_dim = self.base_dim  # subclasses may add states after the base ones
        # IAE of the GNSS and ranging noise (vehicle.adaptive); None: the datasheet's noise as told
        self.iae = NoiseAdaptation(adaptive_window) if adaptive_window else None
        self._gate = gate_threshold(2, gate_probability)
        self._gyro_period_us = round(1e6 / spec.imu_rate_hz)
        self.x: np.ndarray | None = None
        self.P: np.ndarray | None = None
        self.time_us = 0
        self.speed, self.gyro, self.odom_yaw = HeldInput(), HeldInput(), HeldInput()
        self.slip = SlipGuard.for_datasheet(spec.odom_speed_sigma_mps, spec.imu_rate_hz)
        self.counters = EstimatorCounters()
        self.gnss_health = GnssHealth(GnssHealthSpec(gate_probability=gate_probability))
        self.alignment = GnssAlignment()
        self._last_good: tuple[np.ndarray, np.ndarray] | None = None
        self._notices: list[Notice] = []
        self._noticed_until_us = -1
        self._resets_floor = 0

    @property
    def initialized(self) -> bool:
        return self.x is not None

    def handle(self, topic: str, msg: Any) -> None:
        """Apply one measurement; they come in non-decreasing stamp order (older ones are counted)."""
        if isinstance(msg, m.PosePrior):
            self._initialise(msg.pose, msg.covariance, msg.stamp_us)
            return
        if self.x is None:
            self._align(msg)
            return
        if msg.stamp_us < self.time_us:
            self.counters.stale += 1
            return
        if isinstance(msg, (m.ImuSample, m.WheelOdometry)):
            self._inputs(msg)
        elif isinstance(msg, m.GnssFix):
            self._propagate_to(msg.stamp_us)
            self._fuse_gnss(msg)
        elif isinstance(msg, (CooperativeFix, SeenFix)):
            self._propagate_to(msg.stamp_us)
            result = self._cooperative_update(msg)
            self.counters.v2v_fused += int(result.accepted)
            self.counters.v2v_rejected += int(not result.accepted)
        elif isinstance(msg, m.LandmarkSighting):
            self._landmark_sighting(msg)

    def _landmark_sighting(self, msg: m.LandmarkSighting) -> None:
        """A replayed camera sighting of a landmark: this filter has no map and ignores it."""

    def _inputs(self, msg: m.ImuSample | m.WheelOdometry) -> None:
        """Hold the gyro rate, or the wheel speed (slip taken off) and yaw rate, from their stamp on."""
        if isinstance(msg, m.ImuSample):
            self.gyro.sample(msg.stamp_us, float(msg.gyro_radps[2]))
            self.slip.accelerometer(float(msg.accel_mps2[0]))
        else:
            self.speed.sample(msg.stamp_us, self.slip.correct(msg.stamp_us, msg.speed_mps))
            self.odom_yaw.sample(msg.stamp_us, msg.yaw_rate_radps)

    def _cooperative_update(self, fix: CooperativeFix | SeenFix) -> UpdateResult:
        """One neighbour fix by the vehicle's cooperative rule (vehicle.cooperative), its radio noise
        learnt by IAE when that is on."""
        adapt = None if self.iae is None else partial(self.iae.adapt, "ranging")
        errors = self._sighting_errors(fix)  # may grow the state: before the fix reads it
        correction, result = self._rule.fuse(self.x, self.P, fix, self._gate, self.unscented_fixes, adapt, errors)
        if correction is not None:
            self._apply_correction(correction)
        return result

    def _sighting_errors(self, fix: CooperativeFix | SeenFix) -> dict | None:
        """The fix's persisting errors as states (vehicle.cooperative.with_persisting_errors); this
        filter has none."""
        return None

    def _apply_correction(self, correction: Correction) -> None:
        self.x, self.P = apply_correction(self.x, self.P, correction)

    def _initialise(self, pose: np.ndarray, covariance: np.ndarray, stamp_us: int, *, from_fixes: bool = False) -> None:
        """Start at ``pose`` (3,) with covariance (3, 3); the gyro bias from its datasheet spread, the
        GNSS error states (if any) at 0 with theirs, tied to the position when it came ``from_fixes``."""
        self.x = np.zeros(self.base_dim)
        self.x[:3] = pose
        if self._gnss_error is None:
            self.P = np.zeros((4, 4))
            self.P[:3, :3] = covariance
        elif from_fixes:
            self.P = aligned_covariance(covariance, self._gnss_error)
        else:
            self.P = np.diag([0.0, 0.0, 0.0, 0.0] + [self._gnss_error.variance_m2] * 2)
            self.P[:3, :3] = covariance
        self.P[3, 3] = self._spec.gyro_bias_sigma_radps**2
        self.time_us = stamp_us
        for held in (self.speed, self.gyro, self.odom_yaw):
            held.restart(stamp_us)

    def _align(self, msg: Any) -> None:
        """No prior (a restart in flight): align from the GNSS track and the gyro (vehicle.alignment)."""
        if isinstance(msg, m.ImuSample):
            self.alignment.yaw_rate(msg.stamp_us, float(msg.gyro_radps[2]))
        if isinstance(msg, (m.ImuSample, m.WheelOdometry)):
            self._inputs(msg)
        elif isinstance(msg, m.GnssFix):
            aligned = self.alignment.fix(msg.stamp_us, msg.position_m, msg.covariance_m2)
            if aligned is not None:
                self._initialise(*aligned, msg.stamp_us, from_fixes=True)
                self.gnss_health.last_fix_us = msg.stamp_us

    def _propagate_to(self, stamp_us: int) -> None:
        """One prediction from the current time to ``stamp_us`` with the inputs' means over it."""
        if self.x is None or stamp_us <= self.time_us:
            return
        dt, spec = (stamp_us - self.time_us) * 1e-6, self._spec
        speed, speed_factor = self.speed.close(stamp_us)
        gyro, gyro_factor = self.gyro.close(stamp_us)
        odom_yaw, odom_factor = self.odom_yaw.close(stamp_us)
        fresh = self.gyro.stamp_us is not None and stamp_us - self.gyro.stamp_us <= GYRO_STALE_PERIODS * self._gyro_period_us
        rate, rate_var, rate_source = (gyro, spec.gyro_sigma_radps**2 * gyro_factor, self.gyro) if fresh else \
            (odom_yaw, spec.odom_yaw_rate_sigma_radps**2 * odom_factor, self.odom_yaw)
        speed_var = spec.odom_speed_sigma_mps**2 * speed_factor
        if spec.odom_travel_sigma_m:  # along-track error growing with the distance travelled
            speed_var += spec.odom_travel_sigma_m**2 * swept(self.speed.segments) / (dt * dt)
        if spec.odom_turn_sigma_rad and not fresh:  # heading error growing with the angle turned
            rate_var += spec.odom_turn_sigma_rad**2 * swept(rate_source.segments) / (dt * dt)
        steps = ekf.pieces(self.speed.segments, rate_source.segments)
        self._predict(speed, rate, dt, speed_var=speed_var, yaw_rate_var=rate_var,
                      bias_walk_var=spec.gyro_bias_walk_radps_rtsec**2, use_bias=fresh, steps=steps)
        self.time_us = stamp_us

    def _predict(self, speed: float, rate: float, dt: float, **noise: Any) -> None:
        """The motion step on (x, P) (ekf.predict_fast's arguments)."""
        if self._gnss_error is None and self.fast_predict:
            self.x, self.P = ekf.predict_fast(self.x, self.P, speed, rate, dt, **noise)
            return
        self.x, F, Q = self._motion(speed, rate, dt, **noise)
        self._apply_motion(F, Q)

    def _apply_motion(self, F: np.ndarray, Q: np.ndarray) -> None:
        """P <- F P F^T + Q, F and Q (n, n) of one motion step over the whole state."""
        P = F @ self.P @ F.T + Q
        self.P = 0.5 * (P + P.T)

    def _fuse(self, y: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float) -> UpdateResult:
        """One gated EKF update with innovation y (m,), H (m, n), noise R (m, m); heading wrapped."""
        self.x, self.P, result = gated_update(self.x, self.P, y, H, R, gate)
        self.x[2] = wrap_angle(self.x[2])
        return result

    def _set_spread(self, indices: list[int], variances: np.ndarray) -> None:
        """Give the states at ``indices`` these variances, uncorrelated with every other state."""
        added_states.set_spread(self.P, indices, variances)

    def _motion(self, speed: float, rate: float, dt: float, **noise: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The new base state (base_dim,), F and Q (base_dim, base_dim) of one motion step: the unicycle's
        (ekf.motion_model) and the GNSS error states' decay."""
        head, F, Q = ekf.motion_model(self.x[:4], speed, rate, dt, **noise)
        if self._gnss_error is None:
            return head, F, Q
        F, Q = augment_motion(F, Q, self._gnss_error, dt)
        return np.concatenate([head, F[4, 4] * self.x[4:6]]), F, Q

    def gnss_model(self, reported_cov_m2: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What a fix should read (2,), its H (2, state_dim) and the noise (2, 2) of its white part."""
        if self._gnss_error is None:
            H = ekf.H_GNSS if len(self.x) == 4 else np.hstack([ekf.H_GNSS, np.zeros((2, len(self.x) - 4))])
            return self.x[:2], H, reported_cov_m2
        return self.x[:2] + self.x[4:6], observation(len(self.x)), self._gnss_error.white(reported_cov_m2)

    def adapted_noise(self) -> dict[str, np.ndarray] | None:
        """IAE's current GNSS and ranging covariances (None: IAE off, or the window is not full yet)."""
        return None if self.iae is None else self.iae.estimates()

    def _fuse_gnss(self, fix: m.GnssFix) -> None:
        """Fuse a fix only if the GNSS health monitor trusts the receiver and the fix passes its tests."""
        predicted, H, R = self.gnss_model(fix.covariance_m2)
        y, HPH = fix.position_m - predicted, H @ self.P @ H.T
        if self.iae is not None:
            R = self.iae.adapt("gnss", y, HPH, R)
        fix = dataclasses.replace(fix, covariance_m2=R)  # from here on: the white part, or IAE's
        verdict = self.gnss_health.check(fix.stamp_us, y, HPH + R, R)
        if verdict.reset_offset_m is not None:
            self._reset_position(verdict.reset_offset_m, verdict.reset_variance_m2)
        if not verdict.fuse:
            self.counters.gnss_rejected += 1
            return
        self._gnss_update(fix)
        self.counters.gnss_accepted += 1

    def _gnss_update(self, fix: m.GnssFix) -> None:
        """Fuse the fix (its covariance already the white part)."""
        predicted, H, _ = self.gnss_model(fix.covariance_m2)
        self.x, self.P, _ = ekf.gnss_update(self.x, self.P, fix.position_m - predicted, H, fix.covariance_m2, self._gate)

    def _reset_position(self, offset_m: np.ndarray, variance_m2: float) -> None:
        """Jump the position by ``offset_m`` (2,) with per-axis variance ``variance_m2``; decorrelate it."""
        self.x[:2] += offset_m
        self._set_spread([0, 1], np.full(2, variance_m2))
        self.counters.resets += 1

    def cycle(self, t_us: int) -> None:
        """Once per loop cycle: propagate to ``t_us``, notice loss of GNSS fix, and recover from
        divergence (restart from the last good cycle, covariance inflated)."""
        if self.x is None:
            return
        self._propagate_to(t_us)
        self.gnss_health.tick(t_us)
        for stamp_us, healthy, reason in self.gnss_health.transitions:
            self._notice(Notice(stamp_us, SEVERITY_INFO if healthy else SEVERITY_WARNING,
                                f"GNSS {'healthy' if healthy else 'unhealthy'}: {reason}", status_changed=True))
        self.gnss_health.transitions.clear()
        if self._diverged():
            self._recover(t_us)
        else:
            self._remember_good(t_us)

    def _remember_good(self, t_us: int) -> None:
        """Keep this cycle's state as the one to fall back to on divergence."""
        self._last_good = (self.x.copy(), self.P.copy())

    def _diverged(self) -> bool:
        """Non-finite state or a covariance that is no longer (finite and) positive definite."""
        return not (math.isfinite(sum(self.x.tolist())) and ekf.is_spd(self.P))

    def _recover(self, t_us: int) -> None:
        if self._last_good is None:  # diverged before any good cycle: start over from nothing
            self.x, self.P = None, None
            self._notice(Notice(t_us, SEVERITY_WARNING, "estimator reset: diverged before a good cycle"))
            return
        x, P = self._last_good
        self.x, self.P = x.copy(), self._inflated(P)
        self.counters.resets += 1
        self._notice(Notice(t_us, SEVERITY_WARNING, "estimator reset: non-finite or indefinite covariance"))

    def _inflated(self, P: np.ndarray) -> np.ndarray:
        """The fallback covariance after a divergence: inflated, with a floor (none on added states)."""
        floor = np.zeros(len(P))
        floor[:4] = DIVERGENCE_FLOOR
        if self._gnss_error is not None:
            floor[4:6] = self._gnss_error.variance_m2
        return DIVERGENCE_INFLATION * P + np.diag(floor)

    def _notice(self, notice: Notice) -> None:
        """Queue a notice unless it was said already (a replay re-runs cycles)."""
        if notice.stamp_us > self._noticed_until_us:
            self._notices.append(notice)

    def landmark_map(self) -> tuple[np.ndarray, np.ndarray] | None:
        """No map: this estimator localizes only."""
        return None

    def take_notices(self) -> list[Notice]:
        out, self._notices = self._notices, []
        if out:
            self._noticed_until_us = max(self._noticed_until_us, *(n.stamp_us for n in out))
        return out

    def status(self, t_us: int) -> EstimatorStatus:
        """ESTIMATOR_STATUS contents: GPS glitch flag while GNSS is distrusted, the larger GNSS test ratio."""
        flags = mavlink2.ESTIMATOR_ATTITUDE | mavlink2.ESTIMATOR_VELOCITY_HORIZ | mavlink2.ESTIMATOR_POS_HORIZ_REL
        flags |= mavlink2.ESTIMATOR_POS_HORIZ_ABS if self.gnss_health.healthy else mavlink2.ESTIMATOR_GPS_GLITCH
        h = self.gnss_health
        P = self.P if self.P is not None else np.eye(4) * 1e6
        return EstimatorStatus(self.vehicle_id, t_us, flags, max(h.last_test_ratio, h.last_mean_test_ratio),
                               float(np.sqrt(0.5 * (P[0, 0] + P[1, 1]))))

    def estimate(self, t_us: int, reset_counter: int) -> StateEstimate:
        """The estimate at the last cycle (``t_us``) as a StateEstimate (NED, body-frame velocity)."""
        x, P = self.x, self.P
        pose_cov = np.diag([0.0, 0.0, NOT_ESTIMATED_VAR, NOT_ESTIMATED_VAR, NOT_ESTIMATED_VAR, 0.0])
        index = np.array([0, 1, 5])
        pose_cov[np.ix_(index, index)] = P[:3, :3]
        spec = self._spec
        vel_cov = np.diag([spec.odom_speed_sigma_mps**2, NOT_ESTIMATED_VAR, NOT_ESTIMATED_VAR, NOT_ESTIMATED_VAR,
                           NOT_ESTIMATED_VAR, spec.gyro_sigma_radps**2 + P[3, 3]])
        gyro = self.gyro.value if self.gyro.value is not None else 0.0
        return StateEstimate(
            vehicle_id=self.vehicle_id, time_usec=max(t_us, self.time_us),
            position_m=np.array([x[0], x[1], -self._altitude_m]), yaw_rad=float(x[2]),
            velocity_mps=np.array([self.speed.value or 0.0, 0.0, 0.0]), yaw_rate_radps=gyro - float(x[3]),
            pose_covariance=pose_cov, velocity_covariance=vel_cov, reset_counter=reset_counter,
        )

    @property
    def resets(self) -> int:
        """Resets so far; never goes down when a replay restores an older snapshot."""
        return max(self._resets_floor, self.counters.resets)

    def snapshot(self) -> dict:
        """A copy of everything that changes as measurements are fused (for the fusion horizon)."""
        state = {k: self.__dict__[k] for k in _MUTABLE}
        for key in ("x", "P"):
            if state[key] is not None:
                state[key] = state[key].copy()
        for key in ("speed", "gyro", "odom_yaw"):
            state[key] = state[key].copy()
        state["counters"] = shallow_copy(state["counters"])
        state["gnss_health"] = state["gnss_health"].copy()
        state["alignment"] = shallow_copy(state["alignment"])  # its fields are replaced, never changed in place
        state["slip"] = state["slip"].copy()
        if state["iae"] is not None:
            state["iae"] = state["iae"].copy()
        return state

    def restore(self, snapshot: dict) -> None:
        """Go back to a :meth:`snapshot` (notices already given are not given again)."""
        self._resets_floor = self.resets
        self.__dict__.update(snapshot)
        self.__dict__.update(self.snapshot())  # the snapshot stays reusable
