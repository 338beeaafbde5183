"""The vehicle's loop thread, in lockstep (cycles follow the world's ticks) or in realtime (cycles on
wall-clock deadlines mapped from sim time by the world's first clock tick)."""

from __future__ import annotations

import logging
import queue
import threading
import time

from bus import messages as m
from bus.config import SwarmConfig
from bus.process import Pacer
from bus.session import Bus
from vehicle.node import VehicleNode

log = logging.getLogger("swarmloc.vehicle")


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


def run_vehicle(bus: Bus, config: SwarmConfig, vehicle_id: int, stop: threading.Event, *, restarts: int = 0,
                signing_key: bytes | None = None) -> VehicleNode:
    node = VehicleNode(bus, config, vehicle_id, restarts=restarts, signing_key=signing_key)
    (run_lockstep if config.clock.mode == "lockstep" else run_realtime)(node, stop)
    return node
