"""The vehicle process: a fixed-rate loop in sim time around an estimator it knows only by its
interface (``vehicle.estimators``).

Zenoh callbacks only enqueue into bounded mailbox lanes (the world's feed and the clock in one, the
neighbours' broadcasts in another, so a flood of one cannot crowd out the other). The loop thread
(``vehicle.process.loops``) files every item through the bus layer (``vehicle.process.inbound``: parsing, link
faults), hands samples to the fusion horizon, which fuses them in stamp order, and runs the cycles
the clock allows (in lockstep once what ``vehicle.process.lockstep_waits`` names has come);
``vehicle.process.outbound`` publishes the MAVLink stream, the V2V broadcast and the acks.
"""

from __future__ import annotations

import logging

from bus import messages as m
from bus.clock_config import ClockMode
from bus.config import VehicleProcessConfig
from bus.feed import SensorBatch
from bus.landmark_map import LandmarkMap
from bus.mailbox import Mailbox
from bus.rejections import Rejections
from bus.session import Bus, LivelinessEvent, await_subscribers
from bus.topics import Topic
from vehicle.estimators import get_estimator
from vehicle.models.cooperative_fixes import SeenFix
from vehicle.process.fusion import FusionHorizon
from vehicle.process.inbound import (
    MAX_BATCH_BYTES,
    MAX_CLOCK_BYTES,
    MAX_PLAN_BYTES,
    MAX_V2V_BYTES,
    Delivery,
    Inbound,
    Kind,
)
from vehicle.process.input_runs import unpack
from vehicle.process.lockstep_waits import LockstepWaits
from vehicle.process.loop_stats import LoopStats
from vehicle.process.outbound import Outbound
from vehicle.process.sequence import SequenceTracker
from vehicle.process.status import vehicle_status
from vehicle.process.v2v import V2V, fusion_turn_us
from vehicle.process.world_watch import WorldWatch
from vehicle.vision.motion import ANNOUNCE_OFFSET_US

log = logging.getLogger("swarmloc.vehicle")
GS_LISTEN_WAIT_S = 2.0


class VehicleNode:
    def __init__(
        self,
        bus: Bus,
        config: VehicleProcessConfig,
        vehicle_id: int,
        *,
        restarts: int = 0,
        signing_key: bytes | None = None,
    ) -> None:
        self.bus, self.config, self.vehicle_id = bus, config, vehicle_id
        self.restarts = restarts  # a restarted vehicle re-initialises and counts up reset_counter
        keys, vc = bus.keys, config.vehicle
        self.rejections = Rejections(log, f"vehicle {vehicle_id}")
        self.mailbox = Mailbox()
        world, neighbours = self.mailbox.lane("world", max_items=20_000), self.mailbox.lane("v2v", max_items=20_000)
        self.world_lane = world  # the feed, the clock, the fault plan and liveliness
        self.neighbour_lane = neighbours  # the neighbours' V2V frames
        # a realtime vehicle hears the ticks it needs (sim.pace), a lockstep one every tick
        bus.subscribe(keys.pace() if config.clock.mode is ClockMode.REALTIME else keys.clock(), world, MAX_CLOCK_BYTES)
        bus.subscribe(keys.fault_plan(), world, MAX_PLAN_BYTES)
        bus.subscribe(keys.end(), world, MAX_CLOCK_BYTES)
        bus.subscribe(keys.feed(vehicle_id), world, MAX_BATCH_BYTES)
        if vc.cooperation.enabled:  # broadcasts, and (realtime simulation) frames addressed to this vehicle alone
            bus.subscribe(keys.v2v("*"), neighbours, MAX_V2V_BYTES)
            bus.subscribe(keys.v2v_to("*", vehicle_id), neighbours, MAX_V2V_BYTES)
        bus.watch_liveliness(keys.alive("world", "*"), world)
        bus.watch_liveliness(keys.alive("groundstation", "*"), world)
        if vc.cooperation.enabled:
            bus.watch_liveliness(keys.alive("vehicle", "*"), world)
        self.inbound = Inbound(
            keys=keys,
            vehicle_id=vehicle_id,
            vehicles=config.vehicles,
            fault_seed=config.fault_seed,
            faults=config.faults,
            rejections=self.rejections,
        )
        self.outbound = Outbound(bus, config, vehicle_id, signing_key=signing_key)
        self.estimator = get_estimator(config, vehicle_id, reject=self.rejections.reject)
        realtime = config.clock.mode is ClockMode.REALTIME
        self._lockstep = config.clock.mode is ClockMode.LOCKSTEP
        # realtime: a checkpoint every 5 cycles for samples late beyond the allowance (every cycle
        # cost a fifth of a realtime cycle; a late sample replays at most 5 cycles more)
        self.fusion = FusionHorizon(
            self.estimator,
            horizon_us=round(vc.fusion_horizon_s * 1e6),
            every_cycles=5 if realtime else 0,
            after_cycle=frozenset({Topic.RANGING, Topic.SEEN}),
        )
        v2v_period_us, latency_us = round(1e6 / config.sensors.ranging_rate_hz), round(vc.cooperation.latency_s * 1e6)
        if realtime:  # vehicles take turns to fuse an epoch
            room_us = self.fusion.horizon_us - latency_us
            latency_us += fusion_turn_us(vehicle_id, round(1e6 / vc.loop_rate_hz), v2v_period_us, room_us)
        self.v2v = V2V(
            vehicle_id,
            latency_us=latency_us,
            rejections=self.rejections,
            period_us=v2v_period_us,
        )
        self.visual_odometry = None
        if vc.visual_odometry(vehicle_id):  # OpenCV only in a vehicle that needs it
            from vehicle.vision.visual_odometry import VisualOdometry

            self.visual_odometry = VisualOdometry(vehicle_id, detector=vc.features, reject=self.rejections.reject)
        self.sequences = SequenceTracker()
        self.stats = LoopStats()
        self.loop_priority = 0  # realtime: the SCHED_FIFO priority the loop was granted (vehicle.process.scheduling)
        self.period_us = round(1e6 / vc.loop_rate_hz)
        self.next_cycle_us = 0
        self.world_watch = WorldWatch(timeout_s=vc.world_timeout_s)
        self.waits = LockstepWaits(
            vehicle_id, config.vehicle.cooperation.enabled, self.inbound, self.v2v, self.world_watch, bus.keys
        )
        self._deferred: list[int] = []  # lockstep: cycles to run before the next one (``cycle``)

    def join(self, stop=None, *, v2v_wait_s: float = 30.0) -> None:
        """Declare this vehicle alive once what it publishes has listeners: its acks (the world) and
        its MAVLink (the ground station) without limit, its V2V broadcast (the neighbours) for up to
        ``v2v_wait_s``; the world starts only when every vehicle is alive, so no first message is lost."""
        out, announced = self.outbound, False
        while await_subscribers({"ack": out.ack_publisher, "mavlink": out.mavlink_publisher}, timeout_s=1.0, stop=stop):
            if stop is not None and stop.is_set():
                return
            if not announced:
                log.info("vehicle %d waits for the world and the ground station to listen", self.vehicle_id)
                announced = True
        if self.config.vehicle.cooperation.enabled and self.config.vehicles > 1:
            if await_subscribers({"v2v": out.v2v_publisher}, timeout_s=v2v_wait_s, stop=stop):
                log.warning(
                    "vehicle %d: no neighbour listens after %g s; it goes on alone", self.vehicle_id, v2v_wait_s
                )
        self.bus.declare_token(self.bus.keys.alive("vehicle", self.vehicle_id))

    def take(self, item: object) -> m.ClockTick | None:
        """File one mailbox item (None: nothing came); a clock tick is returned to the loop."""
        tick = None
        if item is None:
            return None
        if isinstance(item, LivelinessEvent):
            self.world_watch.on_token(self.bus.keys.parse(item.key), item.alive)
            return None
        for delivery in self.inbound.take(item):
            if delivery.kind is Kind.TICK:
                tick = self._on_tick(delivery.payload)
            else:
                self._deliver(delivery)
        return tick

    def _deliver(self, d: Delivery, arrival: int | None = None) -> None:
        """Hand one delivery on; ``arrival``: a batch sample's number (FusionHorizon.reserve)."""
        if d.kind is Kind.BATCH:
            self._deliver_batch(d.payload)
        elif d.kind is Kind.HELD:
            self.fusion.expect(d.stamp_us)
        elif d.kind is Kind.V2V:
            self.v2v.hear(*d.payload)
        elif d.topic in (Topic.RANGING, Topic.SEEN):
            self.sequences.see(d.topic, d.payload.seq)
            # its fix may come after later cycles ran (a checkpoint then), unless lockstep waits for it
            may_come_late = not self._lockstep or bool(self.inbound.links.faults)
            if self.config.vehicle.cooperation.enabled and self.v2v.hold(d.payload) and may_come_late:
                self.fusion.expect(d.stamp_us)
        else:
            self.sequences.see(d.topic, d.payload.seq)
            if self.visual_odometry is not None and d.topic in (Topic.ODOM, Topic.CAMERA):
                self._visual_odometry(d)
            else:
                self.fusion.push(d.topic, d.payload, arrival)

    def _deliver_batch(self, batch: SensorBatch) -> None:
        """A batch's samples, as one delivery each in ``SensorBatch.samples``' order would hand them on:
        its IMU and wheel samples as one run (vehicle.process.input_runs), unless visual odometry takes the wheels."""
        if self.visual_odometry is not None:
            for topic, msg in batch.samples():
                self._deliver(Delivery(Kind.SAMPLE, topic, msg, msg.stamp_us))
            return
        run, others = unpack(batch, self.fusion.reserve(batch.count()))
        if run is not None:
            for topic, seq0, count in run.blocks:
                self.sequences.see_range(topic, seq0, count)
            self.fusion.push_run(run)
        for arrival, topic, msg in others:
            self._deliver(Delivery(Kind.SAMPLE, topic, msg, msg.stamp_us), arrival)

    def _visual_odometry(self, d: Delivery) -> None:
        """A vehicle on visual odometry has no wheels: its speed is the motion between camera frames,
        announced with the first frame and pushed with the second (vehicle.vision.visual_odometry)."""
        if d.topic is Topic.ODOM:
            return
        for motion in self.visual_odometry.on_frame(d.payload):
            self.fusion.push(Topic.ODOM, motion)
        self.fusion.push(d.topic, d.payload)
        self.fusion.expect(d.stamp_us + ANNOUNCE_OFFSET_US)

    def _on_tick(self, tick: m.ClockTick) -> m.ClockTick:
        """A vehicle that joins a running swarm (a restart) starts from its first tick: what was
        published before it either arrived or never will."""
        if self.waits.first_tick is None:
            self.waits.start(tick)
            if tick.tick > 0:
                self.next_cycle_us = -(-tick.stamp_us // self.period_us) * self.period_us
        return tick

    def cycle(self, t_us: int, *, deferrable: bool = False) -> None:
        """One loop cycle at sim time t_us: fuse everything stamped <= t_us, encode the estimate.

        ``deferrable`` (lockstep, not a tick's last cycle): a cycle whose estimate a ranging measurement
        still waiting for its neighbour's broadcast will revise, and at which nothing is sent on a
        schedule, runs later, just before the next cycle that is not deferred: the same operations in
        the same order, without the provisional pass the fusion horizon's replay would undo."""
        for delivery in self.inbound.release(t_us):
            self._deliver(delivery)
        for fix in self.v2v.mature(t_us):
            self.fusion.push(Topic.SEEN if isinstance(fix, SeenFix) else Topic.RANGING, fix)
        if deferrable and self.v2v.revises(t_us) and self.outbound.quiet_at(t_us):
            self._deferred.append(t_us)
            self.fusion.postpone(t_us)
            return
        for deferred_us in self._deferred:
            self._run_cycle(deferred_us)
        self._deferred.clear()
        self._run_cycle(t_us)

    def _run_cycle(self, t_us: int) -> None:
        self.fusion.cycle(t_us)
        self.outbound.cycle(
            t_us,
            self.estimator,
            self.reset_counter,
            listeners=self.inbound.listeners_at(t_us) if self.outbound.broadcasts_at(t_us) else None,
            behaviour=self.inbound.behaviour,
        )

    def report(self, t_us: int) -> None:
        """After the cycle at ``t_us`` and its loop statistics: the periodic status when one is due. It
        counts that cycle, so the last one of a run says what the final status says (the ground
        station's summary does not depend on which of the two it had last)."""
        if self.outbound.status_due(t_us):
            self.publish_status(t_us)

    @property
    def reset_counter(self) -> int:
        return self.restarts + self.estimator.resets

    def publish_status(self, t_us: int, *, final: bool = False) -> None:
        self.rejections.counts["inbox_full"] = self.mailbox.dropped()
        self.outbound.status(vehicle_status(self, t_us, final=final), self._landmark_map(t_us))

    def _landmark_map(self, t_us: int) -> LandmarkMap | None:
        found = self.estimator.landmark_map()
        return None if found is None else LandmarkMap(self.vehicle_id, t_us, *found)

    def finish_tick(self, tick: m.ClockTick) -> None:
        """Lockstep: publish the tick's MAVLink frames, then acknowledge it. After a ground station
        (re)appeared, or while this process knows no subscriber of its stream, first wait (bounded)
        until it knows one: a publication with no known subscriber is dropped, and lockstep runs fast
        enough to lose seconds that way. The world resumes after a ground station's restart once that
        one listens to the truth, which this vehicle may learn of, with its liveliness token, only
        after the world's next tick (in 4 of 36 restarts under load the frames of 3-7 ticks were lost
        so)."""
        mavlink = self.outbound.mavlink_publisher
        if self.world_watch.gs_arrived or not mavlink.matching_status.matching:
            self.world_watch.gs_arrived = False
            await_subscribers({"mavlink": mavlink}, timeout_s=GS_LISTEN_WAIT_S)
        if tick.final:
            self.publish_status(tick.stamp_us, final=True)
        self.outbound.flush()
        self.outbound.ack(tick.tick)
        self.waits.finished_us = tick.stamp_us

    def cycles_due(self, stamp_us: int) -> list[int]:
        """The fixed-rate cycle times up to ``stamp_us`` that have not run yet."""
        due = list(range(self.next_cycle_us, stamp_us + 1, self.period_us))
        if due:
            self.next_cycle_us = due[-1] + self.period_us
        return due
