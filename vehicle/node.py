"""The vehicle process: a fixed-rate loop in sim time around the estimator core.

Callbacks only enqueue into the inbox; the loop thread (``vehicle.loops``) files every item here:
sensor payloads are decoded, counted, passed through the link faults of the fault plan (this
process's bus layer), then handed to the fusion horizon, which fuses them in stamp order. Each loop
cycle publishes ODOMETRY, and at 1 Hz HEARTBEAT, ESTIMATOR_STATUS and the loop statistics.
"""

from __future__ import annotations

import logging
import queue

import numpy as np

from bus import messages as m
from bus.config import SwarmConfig
from bus.errors import DecodeError
from bus.link_faults import Arrival, LinkFaultStage
from bus.mavlink_codec import MavlinkEncoder, frame_header
from bus.plan import FaultPlan, decode_json
from bus.session import Bus, Envelope
from vehicle.estimator import VehicleEstimator
from vehicle.fusion import FusionHorizon
from vehicle.loop_stats import LoopStats
from vehicle.sequence import SequenceTracker
from vehicle.v2v import V2V

log = logging.getLogger("swarmloc.vehicle")
STATUS_WARNING, STATUS_INFO = 4, 6  # MAV_SEVERITY
DIVERGENCE_INFLATION = 10.0
DIVERGENCE_FLOOR = np.array([1.0, 1.0, 0.01, 1e-4])  # m^2, m^2, rad^2, (rad/s)^2
ODOMETRY_ID = 331  # MAVLINK_MSG_ID_ODOMETRY: the V2V packet
SENSOR_TYPES = {"imu": m.ImuSample, "odom": m.WheelOdometry, "gnss": m.GnssFix, "prior": m.PosePrior,
                "ranging": m.RangeBearing}


class VehicleNode:
    def __init__(self, bus: Bus, config: SwarmConfig, vehicle_id: int, *, restarts: int = 0,
                 signing_key: bytes | None = None) -> None:
        self.bus, self.config, self.vehicle_id = bus, config, vehicle_id
        self.restarts = restarts  # a restarted vehicle re-initialises and counts up reset_counter
        self._last_good: tuple[np.ndarray, np.ndarray] | None = None
        keys = bus.keys
        self.inbox: queue.SimpleQueue = queue.SimpleQueue()
        bus.subscribe(keys.sensors(vehicle_id), self.inbox)
        bus.subscribe(keys.clock(), self.inbox)
        bus.subscribe(keys.fault_plan(), self.inbox)
        if config.vehicle.cooperative:
            bus.subscribe(keys.v2v("*"), self.inbox)  # neighbours' broadcasts
        self._v2v = bus.publisher(keys.v2v(vehicle_id))
        self._v2v_period_us = round(1e6 / config.sensors.ranging_rate_hz)
        self._mavlink = bus.publisher(keys.mavlink(vehicle_id))
        self._ack = bus.publisher(keys.ack(vehicle_id))
        self._status = bus.publisher(keys.status(vehicle_id))
        bus.declare_token(keys.alive("vehicle", vehicle_id))
        self.encoder = MavlinkEncoder(vehicle_id=vehicle_id, signing_key=signing_key)
        self.estimator = VehicleEstimator(vehicle_id=vehicle_id, spec=config.sensors,
                                          gate_probability=config.vehicle.gate_probability,
                                          altitude_m=config.world.altitude_m)
        self.fusion = FusionHorizon(self.estimator, horizon_us=round(config.vehicle.fusion_horizon_s * 1e6))
        self.links = LinkFaultStage(f"v{vehicle_id}", seed=config.world.seed, faults=config.faults)
        self.plan_version = -1
        self.v2v = V2V(vehicle_id, latency_us=round(config.vehicle.v2v_latency_s * 1e6), signing_key=signing_key)
        self.sequences = SequenceTracker()
        self.stats = LoopStats()
        self.decode_errors = 0
        self.period_us = round(1e6 / config.vehicle.loop_rate_hz)
        self.next_cycle_us = 0
        self._next_heartbeat_us = 0
        self._next_status_us = 0
        self._reported_health_us = -1
        self.received: dict[str, int] = {}  # per topic: samples that reached this process (seq + 1)
        self.first_tick_seen = False

    def take(self, envelope: Envelope) -> m.ClockTick | None:
        """File one inbox item: sensors go through the link faults to the fusion horizon; the fault
        plan is applied; a clock tick is returned to the loop."""
        keys = self.bus.keys
        try:
            if envelope.key == keys.clock():
                return self._first_tick(m.decode(m.ClockTick, envelope.payload))
            if envelope.key == keys.fault_plan():
                self._apply_plan(decode_json(FaultPlan, envelope.payload))
                return None
            topic = keys.topic_of(envelope.key)
            if topic == "v2v":
                self._take_v2v(envelope)
                return None
            msg = m.decode(SENSOR_TYPES[topic], envelope.payload)
        except (DecodeError, KeyError) as exc:
            self.decode_errors += 1
            log.warning("vehicle %d dropped a payload on %s: %s", self.vehicle_id, envelope.key, exc)
            return None
        if msg.vehicle_id == self.vehicle_id:
            self.received[topic] = max(self.received.get(topic, 0), msg.seq + 1)
            arrival = Arrival(envelope.key, f"v{msg.vehicle_id}", topic, msg.stamp_us, (topic, msg))
            for item in self.links.offer(arrival):
                self._deliver(item)
        return None

    def _take_v2v(self, envelope: Envelope) -> None:
        """A neighbour's MAVLink frame: through the link faults, then to the V2V side."""
        sender = self.bus.keys.vehicle_of(envelope.key)
        header = frame_header(envelope.payload)
        if sender == self.vehicle_id or header is None or header[2] != ODOMETRY_ID:
            return  # our own stream, or not an estimate
        packet = (sender, header[3], envelope.payload)
        for frame in self.links.offer(Arrival(envelope.key, f"v{sender}", "mavlink", header[3], ("v2v", packet))):
            self._deliver(frame)

    def _deliver(self, item: tuple[str, object]) -> None:
        topic, msg = item
        if topic == "v2v":
            self.v2v.hear(*msg)
            return
        self.sequences.see(topic, msg.seq)
        if topic == "ranging":
            if self.config.vehicle.cooperative:
                self.v2v.hold(msg)
            return
        self.fusion.push(topic, msg)

    def _apply_plan(self, plan: FaultPlan) -> None:
        if plan.version > self.plan_version:
            self.plan_version = plan.version
            self.links.set_plan(plan.faults)

    def _first_tick(self, tick: m.ClockTick) -> m.ClockTick:
        """A vehicle that joins a running swarm (a restart) waits only for samples published after it
        joined: what the world published before its first tick either arrived or never will."""
        self.v2v.on_tick(tick)
        if not self.first_tick_seen:
            self.first_tick_seen = True
            if tick.tick > 0:
                for feed, count in tick.published_by(self.vehicle_id).items():
                    self.received[feed] = max(self.received.get(feed, 0), count)
                self.next_cycle_us = -(-tick.stamp_us // self.period_us) * self.period_us
        return tick

    def feeds_complete(self, tick: m.ClockTick) -> bool:
        """True when every sample the world published up to ``tick`` has arrived (lockstep).

        Zenoh keeps order within a key but not across keys, so a clock tick can overtake the
        samples published before it; the tick's per-feed counts tell what is still on its way.
        Samples held back by a delay fault have arrived: the link fault stage holds them.
        """
        return all(self.received.get(feed, 0) >= count for feed, count in tick.published_by(self.vehicle_id).items())

    def cycle(self, t_us: int) -> None:
        """One loop cycle at sim time t_us: fuse everything stamped <= t_us, publish the estimate."""
        for item in self.links.release(t_us):
            self._deliver(item)
        for fix in self.v2v.mature(t_us):
            self.fusion.push("ranging", fix)
        try:
            self.fusion.cycle(t_us, on_cycle=self._guard)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
            self._recover(t_us, f"{type(exc).__name__}: {exc}")
        if not self.estimator.initialized:
            return
        self._last_good = (self.estimator.x.copy(), self.estimator.P.copy())
        self._report_gnss_health(t_us)
        odometry = self.encoder.odometry(self.estimator.estimate(t_us, self.reset_counter))
        self._mavlink.put(odometry)
        if t_us % self._v2v_period_us == 0:
            self._v2v.put(odometry)  # the V2V packet {id, x_hat, P, t}, at the ranging epochs
        if t_us >= self._next_heartbeat_us:
            self._mavlink.put(self.encoder.heartbeat())
            self._mavlink.put(self.encoder.estimator_status(self.estimator.status(t_us)))
            self._next_heartbeat_us = t_us + round(self.config.vehicle.heartbeat_period_s * 1e6)
        if t_us >= self._next_status_us:
            self.publish_status(t_us)
            self._next_status_us = t_us + round(self.config.vehicle.status_period_s * 1e6)

    def _guard(self, t_us: int) -> None:
        """Divergence guard, run inside the cycle before the fusion horizon's checkpoint."""
        if self.estimator.initialized and self.estimator.diverged():
            self._recover(t_us, "non-finite or indefinite covariance")

    @property
    def reset_counter(self) -> int:
        return self.restarts + self.estimator.counters.resets

    def _recover(self, t_us: int, why: str) -> None:
        """Divergence guard: restart the filter from the last good cycle, covariance inflated; say so."""
        if self._last_good is None:
            raise RuntimeError(f"vehicle {self.vehicle_id}: estimator diverged before its first good cycle: {why}")
        x, P = self._last_good
        self.estimator.reset_from(x, DIVERGENCE_INFLATION * P + np.diag(DIVERGENCE_FLOOR))
        log.warning("vehicle %d: estimator diverged at %d us (%s); reset from the last good state", self.vehicle_id, t_us, why)
        self._mavlink.put(self.encoder.statustext(STATUS_WARNING, f"estimator reset: {why}"[:50]))

    def _report_gnss_health(self, t_us: int) -> None:
        """Every new GNSS health change goes out at once as STATUSTEXT and ESTIMATOR_STATUS."""
        transitions = [t for t in self.estimator.gnss_health.transitions if t[0] > self._reported_health_us]
        self.estimator.gnss_health.transitions.clear()
        for stamp_us, healthy, reason in transitions:
            text = f"GNSS {'healthy' if healthy else 'unhealthy'}: {reason}"
            self._mavlink.put(self.encoder.statustext(STATUS_INFO if healthy else STATUS_WARNING, text[:50]))
            self._reported_health_us = stamp_us
        if transitions:
            self._mavlink.put(self.encoder.estimator_status(self.estimator.status(t_us)))

    def publish_status(self, t_us: int) -> None:
        c, f = self.estimator.counters, self.fusion.counters
        self._status.put(m.encode(m.VehicleStatus(
            self.vehicle_id, t_us, self.stats.cycles, self.stats.overruns, self.stats.jitter_p99_us(),
            self.stats.cycle_p99_us(), c.stale + f.dropped_stale, c.gnss_rejected, self.decode_errors,
            self.reset_counter % 256, f.duplicates, self.sequences.lost, f.late_fused, c.v2v_fused, self.v2v.missing)))

    def acknowledge(self, tick: m.ClockTick) -> None:
        self._ack.put(m.encode(m.TickAck(self.vehicle_id, tick.tick)))

    def cycles_due(self, stamp_us: int) -> list[int]:
        """The fixed-rate cycle times up to ``stamp_us`` that have not run yet."""
        due = list(range(self.next_cycle_us, stamp_us + 1, self.period_us))
        if due:
            self.next_cycle_us = due[-1] + self.period_us
        return due
