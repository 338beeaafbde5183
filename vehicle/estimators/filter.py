"""The vehicle estimator: one ``Filter`` class, composed of the parts it is built from (navlie's
shape: a state, process and measurement models, a filter that takes them). The kinds of part (GNSS
observation, motion, update strategy, store, divergence guard, persisting errors, a measurement part
for sightings or frames) are the Protocols of vehicle.estimators.parts; the neighbour monitor's part
is vehicle.estimators.trust (None with the monitor off). A part is handed the state (a
``FilterState``, everything a replay must restore), the store and what it needs, never the filter.
Messages reach their part by type: the filter's own (inputs, GNSS fixes, neighbours' fixes) and
those its measurement part registers (``handlers``).

The common flow, the same for every estimator: a prior (or, after a restart in flight, the GNSS
track) initialises the state; inputs are held (vehicle.estimators.input_holds) and integrated
between propagations, one per loop cycle or measurement (vehicle.estimators.propagation); GNSS fixes
pass the GNSS health monitor before they are fused (vehicle.estimators.gnss_fusion); neighbours'
fixes are judged by the neighbour monitor and fused by the vehicle's cooperative rule
(vehicle.estimators.neighbour_fusion); each cycle propagates, notices GNSS health changes and
recovers from divergence. Pure: no bus, no clock. The wire format is not the filter's: ``estimate``
and ``health`` return plain records (vehicle.estimators.published).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import Any

import numpy as np

from bus import messages as m
from bus.config import SensorSpec
from bus.estimate import Health, PoseEstimate
from bus.statistics import gate_threshold
from vehicle.estimators import published
from vehicle.estimators.divergence import fall_back
from vehicle.estimators.gnss_fusion import fuse_gnss
from vehicle.estimators.input_holds import hold_imu, hold_row, hold_visual, hold_wheels
from vehicle.estimators.neighbour_fusion import NeighbourFusion
from vehicle.estimators.parts import (
    DivergenceGuard,
    ErrorStates,
    Fusing,
    GnssObservation,
    Handler,
    MeasurementPart,
    MotionModel,
    Store,
    UpdateStrategy,
)
from vehicle.estimators.propagation import close_inputs
from vehicle.estimators.state import (
    SEVERITY_INFO,
    SEVERITY_WARNING,
    EstimatorCounters,
    FilterState,
    Notice,
    Notices,
)
from vehicle.estimators.trust import NeighbourTrust
from vehicle.models.cooperative import CooperativeRule
from vehicle.models.cooperative_fixes import CooperativeFix, SeenFix
from vehicle.trust.neighbours import MonitorSpec
from vehicle.vision.motion import VisualMotion


class Filter:
    """A vehicle estimator (module docstring). Build one with an estimator module's ``build``
    (``vehicle.estimators.get_estimator`` through the registry bus.estimators), not by hand."""

    def __init__(
        self,
        *,
        name: str,
        vehicle_id: int,
        spec: SensorSpec,
        gate_probability: float,
        gnss: GnssObservation,
        motion: MotionModel,
        update: UpdateStrategy,
        store: Store,
        divergence: DivergenceGuard,
        errors: ErrorStates | None = None,
        sightings: MeasurementPart | None = None,
        cooperative: CooperativeRule = CooperativeRule(),
        adaptive_window: int = 0,
        monitor: MonitorSpec | None = MonitorSpec(),
    ) -> None:
        self.name, self.vehicle_id, self.spec = name, vehicle_id, spec
        self.gnss, self.motion, self.update, self.store = gnss, motion, update, store
        self.divergence, self.errors, self.sightings = divergence, errors, sightings
        self.cooperative = cooperative
        self.parts: list[MeasurementPart] = [] if sightings is None else [sightings]  # and add_part's
        paper = cooperative.fusion == "paper"
        self.trust = None if monitor is None else NeighbourTrust(monitor, vehicle_id=vehicle_id, position_fixes=paper)
        self.neighbour_fusion = NeighbourFusion(cooperative, update.unscented_fixes, self.trust)
        self.gate = gate_threshold(2, gate_probability)
        self.gate_probability = gate_probability
        self._adaptive_window = adaptive_window
        self._gyro_period_us = round(1e6 / spec.imu_rate_hz)
        self._camera_period_us = round(1e6 / spec.camera_rate_hz) if spec.camera_rate_hz else 0
        self.state = self._fresh_state()
        self.notices = Notices()
        self._resets_floor = 0
        self._handlers = self._registry()

    def _registry(self) -> dict[type, Callable[[Any], None]]:
        """Which method takes a message of each type: the filter's own kinds, then each measurement
        part's (``MeasurementPart.handlers``), handed a ``Fusing``."""
        handlers: dict[type, Callable[[Any], None]] = {
            m.ImuSample: lambda msg: hold_imu(self.state, msg),
            m.WheelOdometry: lambda msg: hold_wheels(self.state, msg),
            VisualMotion: lambda msg: hold_visual(self.state, msg, self.spec, self._camera_period_us),
            m.GnssFix: self._on_gnss,
            CooperativeFix: self._on_fix,
            SeenFix: self._on_fix,
        }
        for part in self.parts:
            handlers |= {kind: partial(self._on_part, handler) for kind, handler in part.handlers().items()}
        return handlers

    def add_part(self, part: MeasurementPart) -> None:
        """A measurement part besides the estimator's own (an added sensor's, bus.sensors): its message
        kinds reach it as the filter's own do."""
        self.parts.append(part)
        part.start(self.state)
        self._handlers |= {kind: partial(self._on_part, handler) for kind, handler in part.handlers().items()}

    def _fresh_state(self) -> FilterState:
        state = FilterState.fresh(self.spec, self.gate_probability, self._adaptive_window)
        for model in self._models():
            model.start(state)
        return state

    def _models(self) -> list[ErrorStates | MeasurementPart]:
        return ([] if self.errors is None else [self.errors]) + self.parts

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

    def snapshot(self) -> FilterState:
        """A copy of everything that changes as measurements are fused (for the fusion horizon)."""
        return self.state.copy()

    def restore(self, snapshot: FilterState) -> None:
        """Go back to a :meth:`snapshot` (notices already given are not given again); the snapshot
        stays reusable."""
        self._resets_floor = self.resets
        self.state = snapshot.copy()

    def landmark_map(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Landmark positions (m, 2) and covariances (m, 2, 2) of a SLAM map; None without one."""
        return None if self.sightings is None else self.sightings.landmark_map(self.state)

    def estimate(self, t_us: int) -> PoseEstimate:
        """The pose at the last cycle (``t_us``) as published (vehicle.estimators.published)."""
        return published.pose_estimate(self.state, self.spec, self.vehicle_id, t_us)

    def accused(self) -> tuple[int, ...]:
        """The neighbours the monitor distrusts on the vehicle's own evidence (its broadcasts say so)."""
        return self.state.neighbours.accused()

    def health(self, t_us: int) -> Health:
        """GNSS trusted or not, the larger GNSS test ratio, the 1-sigma horizontal accuracy."""
        return published.health(self.state, self.spec, self.vehicle_id, t_us)

    # -- measurements ------------------------------------------------------------------------

    def handle(self, msg: Any) -> None:
        """Apply one measurement; they come in non-decreasing stamp order (older ones are counted).
        A message of a type nothing registered is ignored."""
        s = self.state
        if type(msg) is m.PosePrior:
            self.initialise(msg.pose, msg.covariance, msg.stamp_us)
            return
        if s.x is None:
            self._align(msg)
            return
        if msg.stamp_us < s.time_us:
            s.counters.stale += 1
            return
        handler = self._handlers.get(type(msg))
        if handler is not None:
            handler(msg)

    def handle_row(self, topic: str, stamp_us: int, row: list[float], message: Callable[[], Any]) -> None:
        """An IMU or wheel odometry sample as its feed row (bus.feed.LAYOUT, floats; vehicle.process.input_runs):
        what :meth:`handle` does with its message, which ``message()`` makes where it is needed."""
        s = self.state
        if s.x is None or stamp_us < s.time_us:
            self.handle(message())
        else:
            hold_row(s, topic, stamp_us, row)

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
            model.initialise(s)

    def _align(self, msg: Any) -> None:
        """No prior (a restart in flight): align from the GNSS track and the gyro (vehicle.estimators.alignment)."""
        s, kind = self.state, type(msg)
        if kind is m.ImuSample:
            s.alignment.yaw_rate(msg.stamp_us, float(msg.gyro_radps[2]))
        if kind in (m.ImuSample, m.WheelOdometry, VisualMotion):
            self._handlers[kind](msg)
        elif kind is m.GnssFix:
            aligned = s.alignment.fix(msg.stamp_us, msg.position_m, msg.covariance_m2)
            if aligned is not None:
                self.initialise(*aligned, msg.stamp_us, from_fixes=True)
                self.state.gnss_health.last_fix_us = msg.stamp_us

    def propagate_to(self, stamp_us: int) -> None:
        """One prediction from the current time to ``stamp_us`` with the inputs' means over it
        (vehicle.estimators.propagation)."""
        s = self.state
        if s.x is None or stamp_us <= s.time_us:
            return
        step = close_inputs(s, self.spec, stamp_us, self._gyro_period_us)
        self.update.predict(
            s, self.store, self.motion, self.errors, step.speed_mps, step.rate_radps, step.dt, step.noise
        )
        s.time_us = stamp_us

    def _on_gnss(self, fix: m.GnssFix) -> None:
        s = self.state
        self.propagate_to(fix.stamp_us)
        may_reset = None if self.trust is None else partial(self.trust.allows_reset, s, fix.stamp_us)
        fuse_gnss(s, self.store, self.gnss, fix, self.gate, may_reset=may_reset, reset=self.reset_position)

    def _on_fix(self, fix: CooperativeFix | SeenFix) -> None:
        s = self.state
        self.propagate_to(fix.stamp_us)
        fused = self.neighbour_fusion.fuse(s, self.store, self.errors, fix, self.gate, self.notices.say)
        s.counters.v2v_fused += int(fused)
        s.counters.v2v_rejected += int(not fused)

    def _on_part(self, handler: Handler, msg: Any) -> None:
        """A measurement part's message, handed over with what the part may use (parts.Fusing)."""
        handler(Fusing(self.state, self.store, self.errors, self.gate, self.propagate_to, self.notices.say), msg)

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
            self.notices.say(Notice(stamp_us, severity, text, status_changed=True))
        s.gnss_health.transitions.clear()
        if not self.divergence.diverged(s):
            self.divergence.remember(s, t_us)
            return
        self.notices.say(fall_back(s, partial(self.divergence.inflated, gnss=self.gnss), t_us))
        for model in self._models():
            model.recovered(s)
