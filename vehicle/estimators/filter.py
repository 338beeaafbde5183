"""The vehicle estimator: one ``Filter`` class, composed of the models it is built from (navlie's
shape: a state, process and measurement models, a filter that takes them).

- ``state``: a ``FilterState`` (vehicle.estimators.state), everything a replay must restore;
- ``gnss``: how a fix observes the state (white, or with the receiver's correlated error as two
  states, vehicle.models.gnss);
- ``motion``: the unicycle driven by the held inputs, with the states added after the pose
  (vehicle.models.motion);
- ``update``: the update strategy, linearized (EKF) or unscented (vehicle.estimators.updates);
- ``store``: where (x, P) live and how they change: a dense pair of arrays, a SLAM map changed in
  place, or a block of the centralized reference's joint state (vehicle.estimators.stores);
- ``errors``: the sighting's persisting errors as states (vehicle.models.sighting_errors), if any;
- ``sightings``: what the filter does with landmark sightings and camera frames (none, a surveyed
  map: ``known_map``, a SLAM map: ``ekf_slam``);
- ``divergence``: how a diverged state is detected and recovered from;
- ``trust``: what the filter does with its neighbour monitor (vehicle.estimators.trust), None with
  the monitor off.

The common flow, the same for every estimator: a prior (or, after a restart in flight, the GNSS
track) initialises the state; inputs are held and integrated between propagations (one per loop
cycle or measurement); GNSS fixes pass the GNSS health monitor before they are fused (a position
reset to them is first put to the believed neighbours); neighbours' fixes are judged by the
neighbour monitor (vehicle.neighbours) and fused by the vehicle's cooperative rule (Covariance
Intersection); each cycle propagates, notices GNSS health changes and recovers from divergence.
Pure: no bus, no clock. The wire format is not the filter's: ``estimate`` and ``health`` return
plain records (bus.estimate).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from bus import messages as m
from bus.config import SensorSpec
from bus.estimate import Health, PoseEstimate
from bus.statistics import gate_threshold, published_pose_cov
from bus.topics import Topic
from vehicle.adaptive import NoiseAdaptation
from vehicle.alignment import GnssAlignment
from vehicle.estimators.state import SEVERITY_INFO, SEVERITY_WARNING, EstimatorCounters, FilterState, Notice
from vehicle.estimators.trust import NeighbourTrust
from vehicle.gnss_health import GnssHealth, GnssHealthSpec
from vehicle.inputs import HeldInput, VisualMotion, swept
from vehicle.kalman import UpdateResult
from vehicle.models import unicycle
from vehicle.models.cooperative import CooperativeRule
from vehicle.models.cooperative_fixes import CooperativeFix, SeenFix
from vehicle.neighbours import MonitorSpec
from vehicle.wheel_slip import SlipGuard

GYRO_STALE_PERIODS = 5
VISUAL_STALE_US = 500_000  # visual odometry this old no longer gives the yaw rate (the gyro does)

Reject = Callable[[str, str, str], None]


class Filter:
    """A vehicle estimator (module docstring). Build one with an estimator module's ``build``
    (vehicle.estimators.REGISTRY), not by hand."""

    def __init__(
        self,
        *,
        name: str,
        vehicle_id: int,
        spec: SensorSpec,
        gate_probability: float,
        gnss: Any,
        motion: Any,
        update: Any,
        store: Any,
        divergence: Any,
        errors: Any = None,
        sightings: Any = None,
        cooperative: CooperativeRule = CooperativeRule(),
        adaptive_window: int = 0,
        monitor: MonitorSpec | None = MonitorSpec(),
    ) -> None:
        self.name, self.vehicle_id, self.spec = name, vehicle_id, spec
        self.gnss, self.motion, self.update, self.store = gnss, motion, update, store
        self.divergence, self.errors, self.sightings = divergence, errors, sightings
        self.cooperative, self.trust = cooperative, None if monitor is None else NeighbourTrust(monitor)
        self.gate = gate_threshold(2, gate_probability)
        self.gate_probability = gate_probability
        self._adaptive_window = adaptive_window
        self._gyro_period_us = round(1e6 / spec.imu_rate_hz)
        self._camera_period_us = round(1e6 / spec.camera_rate_hz) if spec.camera_rate_hz else 0
        self.state = self._fresh_state()
        self._notices: list[Notice] = []
        self._noticed_until_us = -1
        self._resets_floor = 0

    def _fresh_state(self) -> FilterState:
        spec = self.spec
        odom_period_us = round(1e6 / spec.odom_rate_hz)
        state = FilterState(
            speed=HeldInput(period_us=odom_period_us),
            gyro=HeldInput(period_us=self._gyro_period_us),
            odom_yaw=HeldInput(period_us=odom_period_us),
            slip=SlipGuard.for_datasheet(spec.odom_speed_sigma_mps, spec.imu_rate_hz),
            gnss_health=GnssHealth(GnssHealthSpec(gate_probability=self.gate_probability)),
            alignment=GnssAlignment(),
            iae=NoiseAdaptation(self._adaptive_window) if self._adaptive_window else None,
            counters=EstimatorCounters(),
        )
        for model in self._models():
            model.start(state)
        return state

    def _models(self) -> list[Any]:
        return [model for model in (self.errors, self.sightings) if model is not None]

    # -- what the node asks -------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        return self.state.x is not None

    @property
    def x(self) -> np.ndarray | None:
        """The mean (n,) (None before the first prior or alignment)."""
        return self.state.x

    @property
    def P(self) -> np.ndarray | None:
        """The covariance (n, n)."""
        return self.state.P

    @property
    def counters(self) -> EstimatorCounters:
        return self.state.counters

    @property
    def resets(self) -> int:
        """Resets so far; never goes down when a replay restores an older snapshot."""
        return max(self._resets_floor, self.state.counters.resets)

    def adapted_noise(self) -> dict[str, np.ndarray] | None:
        """IAE's current GNSS and ranging covariances (None: IAE off, or the window is not full yet)."""
        return None if self.state.iae is None else self.state.iae.estimates()

    def snapshot(self) -> FilterState:
        """A copy of everything that changes as measurements are fused (for the fusion horizon)."""
        return self.state.copy()

    def restore(self, snapshot: FilterState) -> None:
        """Go back to a :meth:`snapshot` (notices already given are not given again); the snapshot
        stays reusable."""
        self._resets_floor = self.resets
        self.state = snapshot.copy()

    def take_notices(self) -> list[Notice]:
        out, self._notices = self._notices, []
        if out:
            self._noticed_until_us = max(self._noticed_until_us, *(n.stamp_us for n in out))
        return out

    def notice(self, notice: Notice) -> None:
        """Queue a notice unless it was said already (a replay re-runs cycles)."""
        if notice.stamp_us > self._noticed_until_us:
            self._notices.append(notice)

    def landmark_map(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Landmark positions (m, 2) and covariances (m, 2, 2) of a SLAM map; None without one."""
        return None if self.sightings is None else self.sightings.landmark_map(self.state)

    def estimate(self, t_us: int) -> PoseEstimate:
        """The pose at the last cycle (``t_us``), the wheel speed and the bias-corrected gyro rate."""
        s, spec = self.state, self.spec
        gyro = s.gyro.value if s.gyro.value is not None else 0.0
        return PoseEstimate(
            vehicle_id=self.vehicle_id,
            stamp_us=max(t_us, s.time_us),
            pose=s.x[:3].copy(),
            pose_cov=published_pose_cov(s.P[:3, :3].copy(), spec.unmodelled_sigma_m),
            speed_mps=s.speed.value or 0.0,
            speed_var=spec.odom_speed_sigma_mps**2,
            yaw_rate_radps=gyro - float(s.x[3]),
            yaw_rate_var=spec.gyro_sigma_radps**2 + s.P[3, 3],
        )

    def accused(self) -> tuple[int, ...]:
        """The neighbours the monitor distrusts on the vehicle's own evidence (its broadcasts say so)."""
        return self.state.neighbours.accused()

    def health(self, t_us: int) -> Health:
        """GNSS trusted or not, the larger GNSS test ratio, the 1-sigma horizontal accuracy."""
        h, P = self.state.gnss_health, self.state.P
        P = P if P is not None else np.eye(4) * 1e6
        ratio = max(h.last_test_ratio, h.last_mean_test_ratio)
        floor = self.spec.unmodelled_sigma_m**2
        return Health(self.vehicle_id, t_us, h.healthy, ratio, float(np.sqrt(0.5 * (P[0, 0] + P[1, 1]) + floor)))

    # -- measurements ------------------------------------------------------------------------

    def handle(self, msg: Any) -> None:
        """Apply one measurement; they come in non-decreasing stamp order (older ones are counted)."""
        s = self.state
        if isinstance(msg, m.PosePrior):
            self.initialise(msg.pose, msg.covariance, msg.stamp_us)
            return
        if s.x is None:
            self._align(msg)
            return
        if msg.stamp_us < s.time_us:
            s.counters.stale += 1
            return
        if isinstance(msg, (m.ImuSample, m.WheelOdometry, VisualMotion)):
            self._inputs(msg)
        elif isinstance(msg, m.GnssFix):
            self.propagate_to(msg.stamp_us)
            self._fuse_gnss(msg)
        elif isinstance(msg, (CooperativeFix, SeenFix)):
            self.propagate_to(msg.stamp_us)
            fused = self._cooperative_update(msg)
            s.counters.v2v_fused += int(fused)
            s.counters.v2v_rejected += int(not fused)
        elif isinstance(msg, m.LandmarkSighting) and self.sightings is not None:
            self.sightings.on_sighting(self, msg)
        elif isinstance(msg, m.CameraFrame) and self.sightings is not None:
            self.sightings.on_frame(self, msg)

    def handle_row(self, topic: str, stamp_us: int, row: list[float], message: Callable[[], Any]) -> None:
        """An IMU or wheel odometry sample as its feed row (bus.feed.LAYOUT, floats; vehicle.input_runs):
        what :meth:`handle` does with its message, which ``message()`` makes where it is needed."""
        s = self.state
        if s.x is None or stamp_us < s.time_us:
            self.handle(message())
        elif topic == Topic.IMU:
            s.gyro.sample(stamp_us, row[2])
            s.slip.accelerometer(row[3])
        else:
            s.speed.sample(stamp_us, s.slip.correct(stamp_us, row[0]))
            s.odom_yaw.sample(stamp_us, row[1])

    def initialise(self, pose: np.ndarray, covariance: np.ndarray, stamp_us: int, *, from_fixes: bool = False) -> None:
        """Start at ``pose`` (3,) with covariance (3, 3): the gyro bias from its datasheet spread, the
        GNSS error states (if any) as the GNSS model says, then the states the models add."""
        s = self.state
        s.x, s.P = self.gnss.initial(pose, covariance, from_fixes)
        s.P[3, 3] = self.spec.gyro_bias_sigma_radps**2
        s.time_us = stamp_us
        for held in (s.speed, s.gyro, s.odom_yaw):
            held.restart(stamp_us)
        for model in self._models():
            model.initialise(self)

    def _inputs(self, msg: m.ImuSample | m.WheelOdometry | VisualMotion) -> None:
        """Hold the gyro rate, or the wheel speed (slip taken off) and yaw rate, or visual odometry's
        speed and yaw rate with the variances of their fit, from their stamp on."""
        s, spec = self.state, self.spec
        if isinstance(msg, m.ImuSample):
            s.gyro.sample(msg.stamp_us, float(msg.gyro_radps[2]))
            s.slip.accelerometer(float(msg.accel_mps2[0]))
        elif isinstance(msg, VisualMotion):
            s.speed.period_us = s.odom_yaw.period_us = self._camera_period_us
            s.speed.sample(msg.stamp_us, msg.speed_mps, msg.speed_var / max(spec.odom_speed_sigma_mps**2, 1e-12))
            if np.isfinite(msg.yaw_rate_var):  # else the yaw rate is unknown: the gyro's
                s.visual_us = msg.stamp_us
                weight = msg.yaw_rate_var / max(spec.odom_yaw_rate_sigma_radps**2, 1e-12)
                s.odom_yaw.sample(msg.stamp_us, msg.yaw_rate_radps, weight)
        else:
            s.speed.sample(msg.stamp_us, s.slip.correct(msg.stamp_us, msg.speed_mps))
            s.odom_yaw.sample(msg.stamp_us, msg.yaw_rate_radps)

    def _align(self, msg: Any) -> None:
        """No prior (a restart in flight): align from the GNSS track and the gyro (vehicle.alignment)."""
        s = self.state
        if isinstance(msg, m.ImuSample):
            s.alignment.yaw_rate(msg.stamp_us, float(msg.gyro_radps[2]))
        if isinstance(msg, (m.ImuSample, m.WheelOdometry, VisualMotion)):
            self._inputs(msg)
        elif isinstance(msg, m.GnssFix):
            aligned = s.alignment.fix(msg.stamp_us, msg.position_m, msg.covariance_m2)
            if aligned is not None:
                self.initialise(*aligned, msg.stamp_us, from_fixes=True)
                self.state.gnss_health.last_fix_us = msg.stamp_us

    def propagate_to(self, stamp_us: int) -> None:
        """One prediction from the current time to ``stamp_us`` with the inputs' means over it: the
        gyro's rate while it is fresh, else the wheels' (their noise growing with the angle turned);
        the speed's noise grows with the distance travelled."""
        s, spec = self.state, self.spec
        if s.x is None or stamp_us <= s.time_us:
            return
        dt = (stamp_us - s.time_us) * 1e-6
        # inputs held past their next sample's due time: what the vehicle's manoeuvres may have changed
        speed_walk = spec.speed_walk_mps_rtsec**2 * s.speed.walk_s(stamp_us)
        gyro_walk, odom_walk = s.gyro.walk_s(stamp_us), s.odom_yaw.walk_s(stamp_us)
        speed, speed_factor = s.speed.close(stamp_us)
        gyro, gyro_factor = s.gyro.close(stamp_us)
        odom_yaw, odom_factor = s.odom_yaw.close(stamp_us)
        # visual odometry's yaw rate, drift-free, beats an integrated gyro whose bias nothing observes
        visual = s.visual_us >= 0 and stamp_us - s.visual_us <= VISUAL_STALE_US
        fresh = (
            not visual
            and s.gyro.stamp_us is not None
            and stamp_us - s.gyro.stamp_us <= GYRO_STALE_PERIODS * self._gyro_period_us
        )
        if fresh:
            rate, rate_var, rate_source = gyro, spec.gyro_sigma_radps**2 * gyro_factor, s.gyro
        else:
            rate, rate_var, rate_source = odom_yaw, spec.odom_yaw_rate_sigma_radps**2 * odom_factor, s.odom_yaw
        rate_var += spec.yaw_rate_walk_radps_rtsec**2 * (gyro_walk if fresh else odom_walk)
        speed_var = spec.odom_speed_sigma_mps**2 * speed_factor + speed_walk
        if spec.odom_travel_sigma_m:  # along-track error growing with the distance travelled
            speed_var += spec.odom_travel_sigma_m**2 * swept(s.speed.segments) / (dt * dt)
        if spec.odom_turn_sigma_rad and not fresh:  # heading error growing with the angle turned
            rate_var += spec.odom_turn_sigma_rad**2 * swept(rate_source.segments) / (dt * dt)
        noise = {
            "speed_var": speed_var,
            "yaw_rate_var": rate_var,
            "bias_walk_var": spec.gyro_bias_walk_radps_rtsec**2,
            "use_bias": fresh,
            "steps": unicycle.pieces(s.speed.segments, rate_source.segments),
        }
        self.update.predict(self, speed, rate, dt, noise)
        s.time_us = stamp_us

    def _fuse_gnss(self, fix: m.GnssFix) -> None:
        """Fuse a fix only if the GNSS health monitor trusts the receiver and the fix passes its tests."""
        s = self.state
        observed = self.gnss.observe(s.x, fix.covariance_m2)
        H = observed.full_H(len(s.x))
        y, HPH = fix.position_m - observed.predicted, H @ s.P @ H.T
        # the fix's noise from here on: the white part of what it reports, or IAE's
        R = observed.R if s.iae is None else s.iae.adapt(Topic.GNSS, y, HPH, observed.R)
        may_reset = None if self.trust is None else partial(self.trust.allows_reset, self, fix.stamp_us)
        verdict = s.gnss_health.check(fix.stamp_us, y, HPH + R, R, may_reset)
        if verdict.reset_offset_m is not None:
            self.reset_position(verdict.reset_offset_m, verdict.reset_variance_m2)
        if not verdict.fuse:
            s.counters.gnss_rejected += 1
            return
        observed = self.gnss.observe(s.x, R)  # the position may have been reset
        y = fix.position_m - observed.predicted
        self.tally_nis("gnss", self.store.update(s, y, observed.H, R, self.gate, observed.idx), len(y))
        s.counters.gnss_accepted += 1

    def _cooperative_update(self, fix: CooperativeFix | SeenFix) -> bool:
        """One neighbour fix by the vehicle's cooperative rule (vehicle.models.cooperative), its radio
        noise learnt by IAE when that is on, its persisting errors as states when the filter keeps them,
        fused only while the neighbour monitor believes the neighbour (vehicle.neighbours). True when
        it was fused."""
        s = self.state
        neighbour = fix.target_id if isinstance(fix, CooperativeFix) else fix.observer_id
        believed = s.neighbours.trusts(neighbour)
        adapt = None if s.iae is None or not believed else partial(s.iae.adapt, Topic.RANGING)
        errors = None if self.errors is None else self.errors.of_fix(self, fix)  # may grow the state: first
        unscented = self.update.unscented_fixes
        correction, result = self.cooperative.fuse(s.x, s.P, fix, self.gate, unscented, adapt, errors)
        if self.trust is not None:
            believed = self.trust.judge(self, neighbour, fix, result)
        if not believed:
            s.counters.v2v_distrusted += 1
            return False
        if correction is not None:
            self.store.correct(s, correction)
        self.tally_nis("robot" if isinstance(fix, CooperativeFix) else "seen", result, 2)
        return result.accepted

    def tally_nis(self, kind: str, result: UpdateResult, dof: int) -> None:
        """Count a fused update's NIS of ``dof`` dimensions under ``kind`` (bus.consistency.NIS_KINDS)."""
        if result.accepted:
            self.state.counters.nis = self.state.counters.nis.add(kind, result.nis, dof)

    def reset_position(self, offset_m: np.ndarray, variance_m2: float) -> None:
        """Jump the position by ``offset_m`` (2,) with per-axis variance ``variance_m2``; decorrelate it."""
        s = self.state
        s.x[:2] += offset_m
        self.store.set_spread(s, [0, 1], np.full(2, variance_m2))
        s.counters.resets += 1
        for model in self._models():
            model.position_reset(s)

    # -- the loop cycle ----------------------------------------------------------------------

    def cycle(self, t_us: int) -> None:
        """Once per loop cycle: propagate to ``t_us``, notice loss of GNSS fix, and recover from
        divergence (restart from the last good state, covariance inflated)."""
        s = self.state
        if s.x is None:
            return
        self.propagate_to(t_us)
        s.gnss_health.tick(t_us)
        for stamp_us, healthy, reason in s.gnss_health.transitions:
            severity = SEVERITY_INFO if healthy else SEVERITY_WARNING
            text = f"GNSS {'healthy' if healthy else 'unhealthy'}: {reason}"
            self.notice(Notice(stamp_us, severity, text, status_changed=True))
        s.gnss_health.transitions.clear()
        if self.divergence.diverged(s):
            self._recover(t_us)
        else:
            self.divergence.remember(s, t_us)

    def _recover(self, t_us: int) -> None:
        s = self.state
        if s.last_good is None:  # diverged before any good cycle: start over from nothing
            s.x, s.P = None, None
            self.notice(Notice(t_us, SEVERITY_WARNING, "estimator reset: diverged before a good cycle"))
        else:
            x, P = s.last_good
            s.x, s.P = x.copy(), self.divergence.inflated(P, self.gnss)
            s.counters.resets += 1
            self.notice(Notice(t_us, SEVERITY_WARNING, "estimator reset: non-finite or indefinite covariance"))
        for model in self._models():
            model.recovered(s)
