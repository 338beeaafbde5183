"""The world process: publishes every vehicle's sensor batch and the truth, drives the clock, ends
the run.

Lockstep: tick k is published only after every live vehicle acknowledged tick k-1 and the ground
station is at most ``gs_lag_ticks`` behind; a vehicle whose liveliness token disappears, or that stays
silent for ``ack_timeout_s``, is dropped from the set and the run goes on. A ground station that is
gone for ``gone_timeout_s`` ends the run (status ``groundstation-lost``). Realtime: the first tick
waits for every vehicle's acknowledgement as in lockstep (their first cycle: vehicle.process.loops), then
ticks follow the wall clock times the speed factor. The next tick's feeds are computed while
vehicles work.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import deque

from bus import messages as m
from bus.clock_config import ClockMode
from bus.config import SwarmConfig
from bus.errors import SwarmlocError
from bus.kill_schedule import KillSchedule
from bus.plan import FaultPlan
from bus.process import Pacer
from bus.rejections import Rejections
from bus.session import Bus, await_subscribers
from sim.intake import WorldIntake
from sim.membership import Membership
from sim.pace import on_pace
from sim.tick_output import EncodedTick, encode_tick, make_world

log = logging.getLogger("swarmloc.world")


class StartTimeout(SwarmlocError):
    """Not every process joined the swarm in time."""


class JoinDeadline:
    """The start's deadline: ``wait_s`` after the last time the count of joined processes grew."""

    def __init__(self, wait_s: float, now: float) -> None:
        self.wait_s, self.deadline, self.joined = wait_s, now + wait_s, 0

    def expired(self, joined: int, now: float) -> bool:
        """Whether the start is over at ``now`` with ``joined`` processes in (a new one moves the deadline)."""
        if joined > self.joined:
            self.deadline, self.joined = now + self.wait_s, joined
        return now > self.deadline


class WorldNode:
    def __init__(self, bus: Bus, config: SwarmConfig) -> None:
        self.bus, self.config, keys = bus, config, bus.keys
        self.world = make_world(config)
        self.rejections = Rejections(log, "world")
        self.kills = KillSchedule()
        self.kills.set_plan(config.faults)  # the plan's first kills held from the start, as the supervisor acts on them
        self.members = Membership(expected=set(self.world.vehicle_ids()))
        self.intake = WorldIntake(bus, self.members, self._apply_plan, self.rejections)
        self.status = "complete"
        bus.declare_token(keys.alive("world", 0))
        self.realtime = config.clock.mode is ClockMode.REALTIME  # realtime vehicles hear the clock's pace (sim.pace)
        control = [keys.clock(), keys.pace()] if self.realtime else [keys.clock()]
        self._publishers: dict[str, object] = {
            key: bus.publisher(key) for key in [*control, keys.truth(), *map(keys.feed, self.members.expected)]
        }
        self.tick_us = round(config.clock.tick_s * 1e6)
        self.ticks_per_second = round(1e6 / self.tick_us)  # of sim time (the pace's, sim.pace)
        self.final_tick = round(config.clock.duration_s * 1e6) // self.tick_us
        self._gs_gone_since: float | None = None
        # the truth of the last ticks (payloads), sent again to a ground station that returns: its
        # predecessor may have died before scoring what it covers
        self._truth_sent: deque[bytes] = deque(maxlen=config.clock.gs_lag_ticks + 2)
        # a simulated world: each batch names who ranges the vehicle, and its V2V frames go to them
        # alone (bus.feed.SensorBatch.listeners); replays broadcast to every vehicle (a data set's
        # robots see each other, which the world does not turn into listeners)
        self.addressed_v2v = config.replay is None

    def publish(self, key: str, payload: bytes) -> None:
        pub = self._publishers.get(key)
        if pub is None:
            pub = self._publishers[key] = self.bus.publisher(key)
        pub.put(payload)

    def drain(self, timeout_s: float, tick: int | None = None) -> None:
        """Handle what the world hears (sim.intake) for up to ``timeout_s``; acks count for ``tick``."""
        self.intake.drain(timeout_s, tick)

    def _apply_plan(self, plan: FaultPlan) -> None:
        """A new fault plan from the ground station: the world applies its physical faults."""
        self.world.faults.replace(plan.faults)
        self.kills.set_plan(plan.faults)

    def wait_for_members(self, stop: threading.Event) -> None:
        """Until every vehicle and the ground station are alive and listen to what the world sends
        them (a publication no subscriber is known for yet would be dropped). The start timeout counts
        from the last process that joined: a large swarm whose processes start one after another on
        a few cores keeps the start as long as it progresses."""
        wait_s = self.config.clock.start_timeout_s
        start = JoinDeadline(wait_s, time.monotonic())
        while not (self.members.everyone_joined() and not await_subscribers(self._publishers, timeout_s=0.0)):
            if stop.is_set():
                return
            if start.expired(self._joined(), time.monotonic()):
                missing = sorted(self.members.expected - self.members.alive)
                who = ([f"vehicles {missing}"] if missing else []) + (
                    [] if self.members.groundstation else ["the ground station"]
                )
                raise StartTimeout(f"{' and '.join(who)} did not join within {wait_s:g} s of the last that did")
            self.drain(0.1)

    def _joined(self) -> int:
        """How many of the processes the run waits for are alive (the vehicles, the ground station)."""
        return len(self.members.alive & self.members.expected) + bool(self.members.groundstation)

    def prepare(self, tick: int) -> EncodedTick:
        """Advance the world to the tick's stamp and encode what it measured (no publishing)."""
        stamp_us = min(tick, self.final_tick) * self.tick_us
        return encode_tick(self.world, self.bus.keys, tick, stamp_us, addressed_v2v=self.addressed_v2v)

    def send(self, prepared: EncodedTick, final: bool) -> None:
        for key, payload in prepared.batches:
            self.publish(key, payload)
        self.publish(self.bus.keys.truth(), prepared.truth)
        self._truth_sent.append(prepared.truth)
        self.members.acked, self.members.started = set(), True
        tick = m.ClockTick(
            prepared.tick,
            prepared.stamp_us,
            time.time_ns(),
            final,
            self.members.v2v_published(self.config.world.vehicles),
            tuple(sorted(self.members.alive | self.members.joining)),
            tuple(sorted(self.members.alive)),
        )
        payload = m.encode(tick)
        self.publish(self.bus.keys.clock(), payload)
        if self.realtime and on_pace(prepared.tick, final=final, ticks_per_second=self.ticks_per_second):
            self.publish(self.bus.keys.pace(), payload)

    def await_acks(self, tick: int, stop: threading.Event, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while not stop.is_set() and not self.members.alive <= self.members.acked:
            if time.monotonic() > deadline:
                for vid in sorted(self.members.alive - self.members.acked):
                    self.members.declare_dead(vid, f"no ack for tick {tick} within {timeout_s:g} s")
                return
            self.drain(0.05, tick)

    def await_final_acks(self, tick: int, finishing: set[int], stop: threading.Event, timeout_s: float) -> None:
        """The final tick: wait for the acknowledgement of every vehicle that was alive when it went
        out, even once its token is gone. A vehicle acknowledges and then leaves, and zenoh does not
        order its ack and its departure (different keys): dropping it on the departure would make
        ``completed`` depend on which arrived first."""
        deadline = time.monotonic() + timeout_s
        while not stop.is_set() and not finishing <= self.members.acked and time.monotonic() < deadline:
            self.drain(0.05, tick)

    def hold_for_kills(self, stamp_us: int, stop: threading.Event) -> None:
        """Lockstep with a supervisor (`swarm up`) present: the clock stays at the tick of a kill fault
        until the vehicle is gone, and at the tick of its restart until the new process is back and
        listens to its feed, so the kill and the rejoin happen at the plan's sim times however long
        a process takes to die or start (bus.kill_schedule). Bounded by ``ack_timeout_s`` and
        ``start_timeout_s``: without anyone executing the fault, the run goes on."""
        for action, vid, name in self.kills.due(stamp_us):
            if not self.members.supervisor or vid not in self.members.expected:
                continue
            if action == "kill":
                timeout_s, done = self.config.clock.ack_timeout_s, lambda: not self._present(vid)
            else:
                feed_publisher = {"feed": self._publishers[self.bus.keys.feed(vid)]}
                timeout_s = self.config.clock.start_timeout_s

                def done() -> bool:
                    return self._present(vid) and not await_subscribers(feed_publisher, timeout_s=0.0)

            deadline = time.monotonic() + timeout_s
            while not done() and not stop.is_set():
                if time.monotonic() > deadline:
                    log.warning(
                        "fault %s: vehicle %d not %s after %g s; the run goes on",
                        name,
                        vid,
                        "gone" if action == "kill" else "back",
                        timeout_s,
                    )
                    break
                self.drain(0.02)

    def _groundstation_listens(self) -> bool:
        return not await_subscribers({"truth": self._publishers[self.bus.keys.truth()]}, timeout_s=0.0)

    def _present(self, vid: int) -> bool:
        return vid in self.members.alive or vid in self.members.joining

    def hand_over_end(self, end: m.RunEnd, stop: threading.Event, timeout_s: float = 10.0) -> None:
        """Publish the run's end and stay until the ground station acknowledges it (an ack of the
        tick after the last) or is gone, at most ``timeout_s``, saying it again each second: a put
        made just before the session closes can be lost, and a ground station that misses the end
        reports the run as world-lost."""
        payload = m.encode(end)
        deadline, next_put = time.monotonic() + timeout_s, 0.0
        while (
            self.members.groundstation
            and self.members.gs_acked <= end.tick
            and time.monotonic() < deadline
            and not stop.is_set()
        ):
            if time.monotonic() >= next_put:
                self.publish(self.bus.keys.end(), payload)
                next_put = time.monotonic() + 1.0
            self.drain(0.05)
        if next_put == 0.0:
            self.publish(self.bus.keys.end(), payload)

    def await_groundstation(self, tick: int, stop: threading.Event, lockstep: bool) -> bool:
        """Lockstep pauses while the ground station lags more than ``gs_lag_ticks`` or is away (a
        restart), so nothing goes unscored. False when it has been gone for ``gone_timeout_s``."""
        clock = self.config.clock
        while not stop.is_set():
            present = self.members.groundstation
            if present:
                self._gs_gone_since = None
            elif self._gs_gone_since is None:
                self._gs_gone_since = time.monotonic()
                log.warning("ground station gone; the run waits up to %g s for it", clock.gone_timeout_s)
            if not present and time.monotonic() - self._gs_gone_since > clock.gone_timeout_s:
                return False
            if present and self.members.gs_returned:
                if not self._groundstation_listens():  # its truth would be dropped
                    self.drain(0.02)
                    continue
                # the new one gets the truth of the last ticks again: its predecessor scores a tick's
                # estimates only at the next tick, so the truth of the last one it acknowledged may
                # be needed too (the vehicles hold their frames until they know the new one
                # listens: vehicle.process.node.VehicleNode.finish_tick). It starts here.
                self.members.gs_returned = False
                for truth in self._truth_sent:
                    self.publish(self.bus.keys.truth(), truth)
                self.members.gs_acked = max(self.members.gs_acked, tick - 1)
            if present and (not lockstep or self.members.gs_acked >= tick - clock.gs_lag_ticks):
                return True
            self.drain(0.02)
        return True


def run_world(bus: Bus, config: SwarmConfig, stop: threading.Event) -> WorldNode:
    """Run the whole simulation; returns the node (for its membership record and status)."""
    node = WorldNode(bus, config)
    node.wait_for_members(stop)
    lockstep = config.clock.mode is ClockMode.LOCKSTEP
    ack_timeout = config.clock.ack_timeout_s
    prepared = node.prepare(0)
    pacer: Pacer | None = None  # realtime: paced from the second tick on, once every vehicle acked the first
    for tick in range(node.final_tick + 1):
        if stop.is_set():
            node.status = "interrupted"
            break
        if not node.await_groundstation(tick, stop, lockstep):
            node.status = "groundstation-lost"
            break
        if pacer is not None:
            time.sleep(max(0.0, pacer.seconds_until(tick * node.tick_us)))
        node.send(prepared, final=False)
        prepared = node.prepare(tick + 1)  # the next tick's feeds, while the vehicles work
        if lockstep:
            node.await_acks(tick, stop, ack_timeout)
            node.hold_for_kills(tick * node.tick_us, stop)
        elif pacer is None:  # every vehicle's first cycle (vehicle.process.loops) is done before the clock starts
            node.await_acks(tick, stop, ack_timeout)
            pacer = Pacer(sim0_us=(tick + 1) * node.tick_us, wall0_ns=time.time_ns(), speed=config.clock.speed)
        else:
            node.drain(0.0)
    _end_run(node, prepared, stop, min(ack_timeout, 5.0))
    return node


def _end_run(node: WorldNode, prepared: EncodedTick, stop: threading.Event, final_ack_timeout_s: float) -> None:
    """The final tick (the next one prepared), the final acks of a complete run, and the run's end."""
    if node.status == "complete":
        finishing = set(node.members.alive)
        node.send(prepared, final=True)
        node.await_final_acks(prepared.tick, finishing, stop, final_ack_timeout_s)
    else:
        log.error("world ends the run early: %s", node.status)
        node.send(prepared, final=True)  # vehicles finish instead of waiting for ticks that never come
    completed = tuple(sorted(node.members.acked)) if node.status == "complete" else ()
    end = m.RunEnd(
        prepared.tick,
        min(prepared.tick, node.final_tick) * node.tick_us,
        len(node.members.alive),
        node.status,
        node.rejections.as_counts(),
        completed,
    )
    node.hand_over_end(end, stop)
