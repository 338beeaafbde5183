"""The vehicle process: a fixed-rate loop in sim time around the estimator core.

Callbacks only enqueue into the inbox; this thread decodes, buffers measurements in stamp order,
runs one estimator cycle per loop period and publishes ODOMETRY (every cycle), HEARTBEAT (1 Hz)
and its loop statistics. Lockstep: cycles run when the world's clock tick arrives, then the tick
is acknowledged. Realtime: cycles run on wall-clock deadlines derived from the world's clock.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import queue
import threading
import time

import numpy as np

from bus import messages as m
from bus.config import SwarmConfig
from bus.errors import DecodeError
from bus.mavlink_codec import MavlinkEncoder
from bus.process import Pacer
from bus.session import Bus, Envelope
from vehicle.estimator import VehicleEstimator
from vehicle.loop_stats import LoopStats

log = logging.getLogger("swarmloc.vehicle")
STATUS_WARNING, STATUS_INFO = 4, 6  # MAV_SEVERITY
DIVERGENCE_INFLATION = 10.0
DIVERGENCE_FLOOR = np.array([1.0, 1.0, 0.01, 1e-4])  # m^2, m^2, rad^2, (rad/s)^2
SENSOR_TYPES = {"imu": m.ImuSample, "odom": m.WheelOdometry, "gnss": m.GnssFix, "prior": m.PosePrior}


class MeasurementBuffer:
    """Decoded measurements ordered by (stamp, arrival); ``pop_until`` hands them out in order."""

    def __init__(self) -> None:
        self._heap: list[tuple[int, int, object]] = []
        self._arrival = itertools.count()

    def push(self, msg: object) -> None:
        heapq.heappush(self._heap, (msg.stamp_us, next(self._arrival), msg))

    def pop_until(self, stamp_us: int) -> list[object]:
        out = []
        while self._heap and self._heap[0][0] <= stamp_us:
            out.append(heapq.heappop(self._heap)[2])
        return out


class VehicleNode:
    def __init__(self, bus: Bus, config: SwarmConfig, vehicle_id: int, *, restarts: int = 0) -> None:
        self.bus, self.config, self.vehicle_id = bus, config, vehicle_id
        self.restarts = restarts  # a restarted vehicle re-initialises and counts up reset_counter
        self._last_good: tuple[np.ndarray, np.ndarray] | None = None
        keys = bus.keys
        self.inbox: queue.SimpleQueue = queue.SimpleQueue()
        bus.subscribe(keys.sensors(vehicle_id), self.inbox)
        bus.subscribe(keys.clock(), self.inbox)
        self._mavlink = bus.publisher(keys.mavlink(vehicle_id))
        self._ack = bus.publisher(keys.ack(vehicle_id))
        self._status = bus.publisher(keys.status(vehicle_id))
        bus.declare_token(keys.alive("vehicle", vehicle_id))
        self.encoder = MavlinkEncoder(vehicle_id=vehicle_id)
        self.estimator = VehicleEstimator(vehicle_id=vehicle_id, spec=config.sensors,
                                          gate_probability=config.vehicle.gate_probability,
                                          altitude_m=config.world.altitude_m)
        self.buffer = MeasurementBuffer()
        self.stats = LoopStats()
        self.decode_errors = 0
        self.period_us = round(1e6 / config.vehicle.loop_rate_hz)
        self.next_cycle_us = 0
        self._next_heartbeat_us = 0
        self._next_status_us = 0
        self.received: dict[str, int] = {}  # per topic: how many samples arrived (seq + 1)

    def take(self, envelope: Envelope) -> m.ClockTick | None:
        """File one inbox item: sensors go to the buffer; a clock tick is returned to the loop."""
        try:
            if envelope.key == self.bus.keys.clock():
                return m.decode(m.ClockTick, envelope.payload)
            msg = m.decode(SENSOR_TYPES[self.bus.keys.topic_of(envelope.key)], envelope.payload)
        except (DecodeError, KeyError) as exc:
            self.decode_errors += 1
            log.warning("vehicle %d dropped a payload on %s: %s", self.vehicle_id, envelope.key, exc)
            return None
        if msg.vehicle_id == self.vehicle_id:
            self.buffer.push(msg)
            topic = self.bus.keys.topic_of(envelope.key)
            self.received[topic] = max(self.received.get(topic, 0), msg.seq + 1)
        return None

    def feeds_complete(self, tick: m.ClockTick) -> bool:
        """True when every sample the world published up to ``tick`` has arrived (lockstep).

        Zenoh keeps order within a key but not across keys, so a clock tick can overtake the
        samples published before it; the tick's per-feed counts tell what is still on its way.
        """
        return all(self.received.get(feed, 0) >= count for feed, count in tick.published_by(self.vehicle_id).items())

    def cycle(self, t_us: int) -> None:
        """One loop cycle at sim time t_us: fuse everything stamped <= t_us, publish the estimate."""
        try:
            for msg in self.buffer.pop_until(t_us):
                self.estimator.handle(msg)
            if self.estimator.initialized:
                self.estimator.tick(t_us)
        except (np.linalg.LinAlgError, FloatingPointError, ValueError) as exc:
            self._recover(t_us, f"{type(exc).__name__}: {exc}")
        if not self.estimator.initialized:
            return
        if self.estimator.diverged():
            self._recover(t_us, "non-finite or indefinite covariance")
        self._last_good = (self.estimator.x.copy(), self.estimator.P.copy())
        self._report_gnss_health(t_us)
        self._mavlink.put(self.encoder.odometry(self.estimator.estimate(t_us, self.reset_counter)))
        if t_us >= self._next_heartbeat_us:
            self._mavlink.put(self.encoder.heartbeat())
            self._mavlink.put(self.encoder.estimator_status(self.estimator.status(t_us)))
            self._next_heartbeat_us = t_us + round(self.config.vehicle.heartbeat_period_s * 1e6)
        if t_us >= self._next_status_us:
            self.publish_status(t_us)
            self._next_status_us = t_us + round(self.config.vehicle.status_period_s * 1e6)

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
        """Every GNSS health change goes out at once as STATUSTEXT and ESTIMATOR_STATUS."""
        transitions = self.estimator.gnss_health.transitions
        for _, healthy, reason in transitions:
            text = f"GNSS {'healthy' if healthy else 'unhealthy'}: {reason}"
            self._mavlink.put(self.encoder.statustext(STATUS_INFO if healthy else STATUS_WARNING, text[:50]))
        if transitions:
            self._mavlink.put(self.encoder.estimator_status(self.estimator.status(t_us)))
            transitions.clear()

    def publish_status(self, t_us: int) -> None:
        c = self.estimator.counters
        self._status.put(m.encode(m.VehicleStatus(
            self.vehicle_id, t_us, self.stats.cycles, self.stats.overruns, self.stats.jitter_p99_us(),
            self.stats.cycle_p99_us(), c.stale, c.gnss_rejected, self.decode_errors, 0)))

    def acknowledge(self, tick: m.ClockTick) -> None:
        self._ack.put(m.encode(m.TickAck(self.vehicle_id, tick.tick)))

    def cycles_due(self, stamp_us: int) -> list[int]:
        """The fixed-rate cycle times up to ``stamp_us`` that have not run yet."""
        due = list(range(self.next_cycle_us, stamp_us + 1, self.period_us))
        if due:
            self.next_cycle_us = due[-1] + self.period_us
        return due


def run_lockstep(node: VehicleNode, stop: threading.Event) -> None:
    """Cycles follow the world's ticks; each tick is acknowledged once its cycles have run."""
    while not stop.is_set():
        try:
            tick = node.take(node.inbox.get(timeout=0.2))
        except queue.Empty:
            continue
        if tick is None:
            continue
        _wait_for_feeds(node, tick, stop)
        for t_us in node.cycles_due(tick.stamp_us):
            start = time.perf_counter()
            node.cycle(t_us)
            node.stats.record(jitter_us=0.0, cycle_us=(time.perf_counter() - start) * 1e6, overran=False)
        if tick.final:
            node.publish_status(tick.stamp_us)
        node.acknowledge(tick)
        if tick.final:
            return


def _wait_for_feeds(node: VehicleNode, tick: m.ClockTick, stop: threading.Event, timeout_s: float = 2.0) -> None:
    """Keep filing inbox items until the feeds up to ``tick`` are complete (or time runs out)."""
    deadline = time.monotonic() + timeout_s
    while not node.feeds_complete(tick) and not stop.is_set() and time.monotonic() < deadline:
        try:
            node.take(node.inbox.get(timeout=0.05))
        except queue.Empty:
            pass
    if not node.feeds_complete(tick):
        log.warning("vehicle %d: feeds up to %d us incomplete; cycling without them", node.vehicle_id, tick.stamp_us)


def run_realtime(node: VehicleNode, stop: threading.Event) -> None:
    """Cycles run on wall-clock deadlines mapped from sim time by the world's first clock tick."""
    pacer: Pacer | None = None
    speed = node.config.clock.speed
    while not stop.is_set():
        timeout = 0.2 if pacer is None else max(0.0, min(0.2, pacer.seconds_until(node.next_cycle_us)))
        try:
            tick = node.take(node.inbox.get(timeout=timeout))
        except queue.Empty:
            tick = None
        if tick is not None:
            pacer = pacer or Pacer(sim0_us=tick.stamp_us, wall0_ns=tick.wall_ns, speed=speed)
            if tick.final:
                node.publish_status(tick.stamp_us)
                node.acknowledge(tick)
                return
        if pacer is not None and pacer.seconds_until(node.next_cycle_us) <= 0:
            _realtime_cycle(node, pacer)


def _realtime_cycle(node: VehicleNode, pacer: Pacer) -> None:
    t_us = node.next_cycle_us
    node.next_cycle_us += node.period_us
    jitter_us = -pacer.seconds_until(t_us) * 1e6
    start = time.perf_counter()
    node.cycle(t_us)
    cycle_us = (time.perf_counter() - start) * 1e6
    node.stats.record(jitter_us=jitter_us, cycle_us=cycle_us, overran=pacer.seconds_until(node.next_cycle_us) < 0)


def run_vehicle(bus: Bus, config: SwarmConfig, vehicle_id: int, stop: threading.Event) -> VehicleNode:
    node = VehicleNode(bus, config, vehicle_id)
    (run_lockstep if config.clock.mode == "lockstep" else run_realtime)(node, stop)
    return node
