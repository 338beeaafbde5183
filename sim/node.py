"""The world process: publishes truth and sensor feeds, drives the clock, ends the run.

Lockstep: tick k is published only after every live vehicle acknowledged tick k-1; a vehicle whose
liveliness token disappears, or that stays silent for ``ack_timeout_s``, is dropped from the set
and the run goes on. Realtime: ticks follow the wall clock times the speed factor.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from dataclasses import dataclass, field

from bus import messages as m
from bus.config import SwarmConfig
from bus.errors import DecodeError, SwarmlocError
from bus.plan import FaultPlan, decode_json
from bus.process import Pacer
from bus.session import Bus, Envelope, LivelinessEvent
from sim.world import World

log = logging.getLogger("swarmloc.world")


class StartTimeout(SwarmlocError):
    """Not every process joined the swarm in time."""


@dataclass
class Membership:
    """Which vehicles are alive and which have acknowledged the current tick."""

    expected: set[int]
    alive: set[int] = field(default_factory=set)
    joining: set[int] = field(default_factory=set)  # restarted: in lockstep once their first ack arrives
    groundstation: bool = False
    acked: set[int] = field(default_factory=set)
    dead: set[int] = field(default_factory=set)

    def on_liveliness(self, event: LivelinessEvent, prefix: str) -> None:
        parts = event.key[len(prefix) + 1:].split("/")  # alive/<role>/<id>
        if len(parts) != 3:
            return
        if parts[1] == "groundstation":
            self.groundstation = event.alive
        elif parts[1] == "vehicle" and parts[2].isdigit():
            vid = int(parts[2])
            if event.alive and vid in self.dead:
                log.info("vehicle %d is back; it joins the lockstep set with its first ack", vid)
                self.dead.discard(vid)
                self.joining.add(vid)
            elif event.alive:
                self.alive.add(vid)
            elif vid in self.alive or vid in self.joining:
                self.joining.discard(vid)
                self.declare_dead(vid, "liveliness lost")

    def declare_dead(self, vid: int, reason: str) -> None:
        log.warning("vehicle %d leaves the lockstep set: %s", vid, reason)
        self.alive.discard(vid)
        self.dead.add(vid)

    def everyone_joined(self) -> bool:
        return self.groundstation and self.expected <= self.alive


class WorldNode:
    def __init__(self, bus: Bus, config: SwarmConfig) -> None:
        self.bus, self.config = bus, config
        self.world = World(config)
        self.inbox: queue.SimpleQueue = queue.SimpleQueue()
        bus.watch_liveliness(f"{bus.keys.prefix}/alive/**", self.inbox)
        bus.subscribe(f"{bus.keys.prefix}/ctl/ack/*", self.inbox)
        bus.subscribe(bus.keys.fault_plan(), self.inbox)
        self.plan_version = -1
        self.gave_up_on_groundstation = False
        bus.declare_token(bus.keys.alive("world", 0))
        self.members = Membership(expected=set(self.world.vehicle_ids()))
        self._publishers: dict[str, object] = {}
        self.tick_us = round(config.clock.tick_s * 1e6)
        self.final_tick = round(config.clock.duration_s * 1e6) // self.tick_us

    def publish(self, key: str, payload: bytes) -> None:
        pub = self._publishers.get(key)
        if pub is None:
            pub = self._publishers[key] = self.bus.publisher(key)
        pub.put(payload)

    def drain(self, timeout_s: float, tick: int | None = None) -> None:
        """Handle inbox items (liveliness, acks of ``tick``) for up to ``timeout_s``."""
        try:
            item = self.inbox.get(timeout=timeout_s)
        except queue.Empty:
            return
        while True:
            if isinstance(item, LivelinessEvent):
                self.members.on_liveliness(item, self.bus.keys.prefix)
            elif isinstance(item, Envelope) and item.key == self.bus.keys.fault_plan():
                self._on_plan(item)
            elif isinstance(item, Envelope):
                self._on_ack(item, tick)
            try:
                item = self.inbox.get_nowait()
            except queue.Empty:
                return

    def _on_plan(self, envelope: Envelope) -> None:
        """A new fault plan from the ground station: the world applies its physical faults."""
        try:
            plan = decode_json(FaultPlan, envelope.payload)
        except DecodeError as exc:
            log.warning("world dropped a malformed fault plan: %s", exc)
            return
        if plan.version > self.plan_version:
            self.plan_version = plan.version
            self.world.faults.replace(plan.faults)

    def _on_ack(self, envelope: Envelope, tick: int | None) -> None:
        try:
            ack = m.decode(m.TickAck, envelope.payload)
        except DecodeError as exc:
            log.warning("world dropped a malformed ack on %s: %s", envelope.key, exc)
            return
        if ack.tick == tick:
            self.members.acked.add(ack.vehicle_id)
            if ack.vehicle_id in self.members.joining:
                self.members.joining.discard(ack.vehicle_id)
                self.members.alive.add(ack.vehicle_id)

    def wait_for_members(self, stop: threading.Event) -> None:
        deadline = time.monotonic() + self.config.clock.start_timeout_s
        while not self.members.everyone_joined():
            if stop.is_set():
                return
            if time.monotonic() > deadline:
                missing = sorted(self.members.expected - self.members.alive)
                gs = "" if self.members.groundstation else " and the ground station"
                raise StartTimeout(f"vehicles {missing}{gs} did not join within "
                                   f"{self.config.clock.start_timeout_s:g} s")
            self.drain(0.1)

    def send_tick(self, tick: int, final: bool) -> None:
        stamp = min(tick, self.final_tick) * self.tick_us
        for key, payload in self.world.advance(stamp):
            self.publish(key, payload)
        self.members.acked = set()
        self.publish(self.bus.keys.clock(), m.encode(m.ClockTick(tick, stamp, time.time_ns(), final, self.world.published(),
                                                                 self.world.comm_jammed(stamp))))

    def await_acks(self, tick: int, stop: threading.Event, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while not stop.is_set() and not self.members.alive <= self.members.acked:
            if time.monotonic() > deadline:
                for vid in sorted(self.members.alive - self.members.acked):
                    self.members.declare_dead(vid, f"no ack for tick {tick} within {timeout_s:g} s")
                return
            self.drain(0.05, tick)
        self.await_groundstation(stop)

    def await_groundstation(self, stop: threading.Event) -> None:
        """Lockstep pauses while the ground station is away (a restart), so that nothing goes
        unscored; after ``start_timeout_s`` the run goes on without it."""
        if self.members.groundstation or self.gave_up_on_groundstation:
            return
        log.warning("ground station gone; lockstep waits up to %g s for it", self.config.clock.start_timeout_s)
        deadline = time.monotonic() + self.config.clock.start_timeout_s
        while not stop.is_set() and not self.members.groundstation and time.monotonic() < deadline:
            self.drain(0.05)
        self.gave_up_on_groundstation = not self.members.groundstation


def run_world(bus: Bus, config: SwarmConfig, stop: threading.Event) -> WorldNode:
    """Run the whole simulation; returns the node (for its membership record)."""
    node = WorldNode(bus, config)
    node.wait_for_members(stop)
    lockstep = config.clock.mode == "lockstep"
    pacer = Pacer(sim0_us=0, wall0_ns=time.time_ns(), speed=config.clock.speed)
    ack_timeout = config.clock.ack_timeout_s
    for tick in range(node.final_tick + 1):
        if stop.is_set():
            break
        if not lockstep:
            time.sleep(max(0.0, pacer.seconds_until(tick * node.tick_us)))
        node.send_tick(tick, final=False)
        if lockstep:
            node.await_acks(tick, stop, ack_timeout)
        else:
            node.drain(0.0)
    end_tick = node.final_tick + 1
    node.send_tick(end_tick, final=True)
    node.await_acks(end_tick, stop, min(ack_timeout, 5.0))
    node.publish(bus.keys.end(), m.encode(m.RunEnd(end_tick, node.final_tick * node.tick_us, len(node.members.alive))))
    return node
