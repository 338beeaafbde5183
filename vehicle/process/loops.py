"""The vehicle's loop thread, in lockstep (cycles follow the world's ticks) or in realtime (the first
cycle on the world's first tick, the others on wall-clock deadlines mapped from sim time by the
world's second clock tick, at the vehicle's own phase of the period)."""

from __future__ import annotations

import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable

from bus import messages as m
from bus.clock_config import ClockMode
from bus.config import VehicleProcessConfig
from bus.process import Pacer
from bus.session import Bus
from vehicle.process.node import VehicleNode
from vehicle.process.scheduling import ask_for_realtime_priority

log = logging.getLogger("swarmloc.vehicle")
READY_TIMEOUT_S = 5.0
END_WAIT_S = 10.0  # after the final ack: the world waits up to 5 s for every final ack, then ends the run
ACK_REPEAT_S = 0.5


def run_lockstep(node: VehicleNode, stop: threading.Event) -> None:
    """Cycles follow the world's ticks; each tick is acknowledged once its cycles have run."""
    ticks: deque[m.ClockTick] = deque()
    while not stop.is_set():
        if not ticks:
            node.world_watch.check()
            tick = node.take(node.mailbox.get(0.2, quiet_lane=node.neighbour_lane))  # the clock wakes it
            if tick is not None:
                ticks.append(tick)
            continue
        tick = ticks.popleft()
        _wait_until_ready(node, tick, ticks, stop)
        for t_us in node.cycles_due(tick.stamp_us):
            _wait_for_neighbours(node, tick, t_us, ticks, stop)
            start = time.perf_counter()
            node.cycle(t_us, deferrable=t_us < tick.stamp_us)
            node.stats.record(jitter_us=0.0, cycle_us=(time.perf_counter() - start) * 1e6, overran=False)
            node.report(t_us)
        node.finish_tick(tick)
        if tick.final:
            return


def _file_until(
    node: VehicleNode, done, later: deque, stop: threading.Event, awaited: Callable[[], Iterable[int]]
) -> None:
    """Keep filing mailbox items (clock ticks that come meanwhile go to ``later``) until ``done()``
    or READY_TIMEOUT_S is over. The neighbours' frames wake the loop only once every neighbour it
    still waits for (``awaited()``) has sent one; the others' are filed once it is awake."""
    deadline = time.monotonic() + READY_TIMEOUT_S
    while not done() and not stop.is_set() and time.monotonic() < deadline:
        senders = node.waits.senders_by_key(awaited())
        newer = node.take(node.mailbox.get(0.05, quiet_lane=node.neighbour_lane, senders_by_key=senders))
        if newer is not None:
            later.append(newer)


def _wait_until_ready(node: VehicleNode, tick: m.ClockTick, later: deque, stop: threading.Event) -> None:
    """Keep filing mailbox items until the tick's inputs are complete (or time runs out)."""
    _file_until(node, lambda: node.waits.ready(tick), later, stop, lambda: node.waits.unheard_senders(tick))
    if not node.waits.ready(tick):
        log.warning(
            "vehicle %d: inputs up to %d us incomplete after %g s (missing %s); cycling without them",
            node.vehicle_id,
            tick.stamp_us,
            READY_TIMEOUT_S,
            node.waits.missing_inputs(tick),
        )
        node.waits.write_off_missing(tick)


def _wait_for_neighbours(node: VehicleNode, tick: m.ClockTick, t_us: int, later: deque, stop: threading.Event) -> None:
    """Keep filing mailbox items until the neighbours' broadcasts the cycle at ``t_us`` pairs ranging
    with have arrived (or time runs out: they are then written off as missing). What the cycle
    waits for is found once; each item filed then only crosses off what it brought."""
    unheard = node.waits.unheard_neighbours(tick, t_us)
    if not unheard:
        return

    def heard_all() -> bool:
        nonlocal unheard
        unheard = node.waits.still_unheard(unheard)
        return not node.waits.waited_for(unheard)

    _file_until(node, heard_all, later, stop, lambda: {j for j, _ in unheard})
    unheard = node.waits.waited_for(node.waits.still_unheard(unheard))
    if unheard:
        log.warning(
            "vehicle %d: broadcasts %s (neighbour, stamp us) not heard after %g s; fusing without them",
            node.vehicle_id,
            unheard,
            READY_TIMEOUT_S,
        )
        node.waits.write_off_unheard(unheard)


def schedule_phase_s(vehicle_id: int, vehicles: int, period_s: float) -> float:
    """How long after the world's tick at sim time t vehicle ``vehicle_id`` (1..``vehicles``) runs its
    realtime cycle at t: i / (N + 1) of a period. Independent autopilots are not phase-locked to each
    other; spreading them over the period means the host runs one vehicle's cycle at a time instead
    of all N at the instant the world publishes (which made the last one late by N cycles' work)."""
    return period_s * ((vehicle_id - 1) % vehicles + 1) / (vehicles + 1)


def run_realtime(node: VehicleNode, stop: threading.Event) -> None:
    """The run's first cycle runs on the world's first tick (``_first_cycle``); the others on
    wall-clock deadlines mapped from sim time by the next clock tick, the first the world paces (the
    wall time it was sent), each vehicle ``vehicle.realtime.feed_lead_s`` after the world's tick
    (the time its sensor batch is given to arrive) plus its own phase of the period
    (``schedule_phase_s``). A vehicle that joins a running swarm (a restart) maps them by the first
    tick it sees. After a cycle the loop files what
    has arrived, one item at a time, until the mailbox is empty or the next deadline comes, then
    sleeps to the deadline (zenoh's thread only queues what arrives meanwhile, it does not wake the
    loop); at the deadline it files until the sensor batch covering the cycle is in, waiting up to
    ``realtime.allowance_s`` for it, and runs the cycle (a late loop first files what the world sent:
    a batch may be queued behind). A flood of the neighbours' messages can delay filing, never a
    cycle. The final clock tick ends the loop once the cycles up to its stamp have run. The loop's
    thread asks for real-time scheduling first (``vehicle.realtime.priority``, vehicle.process.scheduling)."""
    node.loop_priority = ask_for_realtime_priority(node.config.vehicle.realtime.priority)
    pacer: Pacer | None = None
    final: m.ClockTick | None = None  # the world has ended the run at final.stamp_us
    allowance_s = node.config.vehicle.realtime.allowance_s
    speed = node.config.clock.speed
    phase_s = schedule_phase_s(node.vehicle_id, node.config.vehicles, node.period_us * 1e-6) / speed
    phase_ns = round((node.config.vehicle.realtime.feed_lead_s + phase_s) * 1e9)
    early: deque[m.ClockTick] = deque()  # ticks filed while the first cycle waited for its batch
    while not stop.is_set():
        if final is not None and node.next_cycle_us > final.stamp_us:
            node.publish_status(final.stamp_us, final=True)
            node.outbound.send_held()
            node.outbound.flush()
            node.outbound.ack(final.tick)
            return
        node.world_watch.check()
        tick = _next_tick(node, pacer, early, allowance_s)
        if tick is None:
            continue
        if pacer is None and tick.tick == 0 and not tick.final:
            _first_cycle(node, tick, early, stop)
            continue
        pacer = pacer or Pacer(sim0_us=tick.stamp_us, wall0_ns=tick.wall_ns + phase_ns, speed=speed)
        if tick.final:
            final = tick  # the cycles up to its stamp still run (its batch may come after it: keys are not ordered)


def _next_tick(node: VehicleNode, pacer: Pacer | None, early: deque, allowance_s: float) -> m.ClockTick | None:
    """The clock tick the loop handles next, if any: one kept while the first cycle waited, else what
    filing (before the clock is known) or a realtime step (after) brings."""
    if early:
        return early.popleft()
    return node.take(node.mailbox.get(0.2)) if pacer is None else _realtime_step(node, pacer, allowance_s)


def _first_cycle(node: VehicleNode, tick: m.ClockTick, early: deque, stop: threading.Event) -> None:
    """The run's first cycle, on the world's first tick, once the tick's sensor batch is in (or
    READY_TIMEOUT_S is over; ticks filed meanwhile go to ``early``): it has no deadline, so it counts
    no jitter; then the tick is acknowledged. The world starts pacing its clock once every vehicle
    has done so: what a process does once (its first batch, the estimator's start, its first
    estimate out) costs 3-4 times a later cycle, and 20 vehicles doing it at their first deadlines
    held the world's next ticks back by tens of milliseconds (docs/decisions/performance.md)."""
    _file_until(node, lambda: node.inbound.received_stamp_us >= tick.stamp_us, early, stop, lambda: ())
    _realtime_cycle(node, None)
    node.outbound.ack(tick.tick)


def _realtime_step(node: VehicleNode, pacer: Pacer, allowance_s: float) -> m.ClockTick | None:
    """One step of the realtime loop: before the deadline, file one item or sleep to the deadline;
    at it, run the cycle once its batch is in, else file (waiting up to the allowance for the batch;
    past it, only what the world sent, and cycle without the batch when none is queued). Returns the
    clock tick it filed, if any."""
    until = pacer.seconds_until(node.next_cycle_us)
    if until > 0:
        item = node.mailbox.get_nowait()
        if item is None:
            time.sleep(min(until, 0.2))
        return node.take(item)
    if node.inbound.received_stamp_us >= node.next_cycle_us:
        _realtime_cycle(node, pacer)
        return None
    if until > -allowance_s:
        return node.take(node.mailbox.get(until + allowance_s))
    item = node.mailbox.get_nowait_from(node.world_lane)
    if item is None:
        _realtime_cycle(node, pacer)
    return node.take(item)


def _realtime_cycle(node: VehicleNode, pacer: Pacer | None) -> None:
    """The next cycle, timed against ``pacer``'s deadlines (None: a cycle with none)."""
    t_us = node.next_cycle_us
    node.next_cycle_us += node.period_us
    jitter_us = None if pacer is None else -pacer.seconds_until(t_us) * 1e6
    start = time.perf_counter()
    node.cycle(t_us)
    node.outbound.flush()
    cycle_us = (time.perf_counter() - start) * 1e6
    overran = pacer is not None and pacer.seconds_until(node.next_cycle_us) < 0
    node.stats.record(jitter_us=jitter_us, cycle_us=cycle_us, overran=overran)
    node.report(t_us)


def run_vehicle(
    bus: Bus,
    config: VehicleProcessConfig,
    vehicle_id: int,
    stop: threading.Event,
    *,
    restarts: int = 0,
    signing_key: bytes | None = None,
) -> VehicleNode:
    node = VehicleNode(bus, config, vehicle_id, restarts=restarts, signing_key=signing_key)
    node.join(stop)
    (run_lockstep if config.clock.mode is ClockMode.LOCKSTEP else run_realtime)(node, stop)
    if not stop.is_set():
        hand_over_end(node, stop)
    return node


def hand_over_end(node: VehicleNode, stop: threading.Event) -> None:
    """After the final tick's acknowledgement, keep the session open until the world ends the run
    (its RunEnd comes once every final ack is in), saying the ack again every ``ACK_REPEAT_S``; at
    most ``END_WAIT_S``, and not for a world that is gone. Closing the session right after the last
    puts lost them now and then (20 vehicles ending together in realtime: a vehicle's final
    estimate, status or ack in about one run in 25; the world then waited 5 s for the ack and named
    the vehicle lost)."""
    if node.outbound.acked_tick is None:
        return
    now = time.monotonic()
    deadline, next_ack = now + END_WAIT_S, now + ACK_REPEAT_S
    while node.inbound.run_end is None and not stop.is_set() and node.world_watch.gone_since is None:
        now = time.monotonic()
        if now >= deadline:
            log.warning("the world did not end the run within %g s of the final ack", END_WAIT_S)
            return
        if now >= next_ack:
            node.outbound.ack(node.outbound.acked_tick)
            next_ack = now + ACK_REPEAT_S
        node.take(node.mailbox.get(min(0.05, deadline - now)))
