"""A vehicle's end of run (vehicle.process.loops.hand_over_end): its session stays open after the final
acknowledgement until the world ends the run, and the ack is said again meanwhile, so that an ack
lost on the way (or in the session's close) does not leave the world waiting for it."""

from __future__ import annotations

import logging
import threading

from bus import messages as m
from bus.config import SwarmConfig
from bus.mailbox import Mailbox
from bus.memory import MemoryHub
from vehicle.process import loops
from vehicle.process.node import VehicleNode

FINAL_TICK = 7


def _ended_node() -> tuple[VehicleNode, MemoryHub, Mailbox]:
    """A vehicle that has acknowledged its final tick, and the world's inbox of acknowledgements."""
    hub = MemoryHub()
    node = VehicleNode(hub.connect("vehicle"), SwarmConfig().for_vehicle(), 1)
    acks = Mailbox()
    hub.connect("world").subscribe(node.bus.keys.ack("*"), acks.lane("acks"))
    node.outbound.ack(FINAL_TICK)
    return node, hub, acks


def _acked_ticks(acks: Mailbox) -> list[int]:
    ticks = []
    while (item := acks.get_nowait()) is not None:
        ticks.append(m.decode(m.TickAck, item.payload).tick)
    return ticks


def test_the_final_ack_is_said_again_until_the_world_ends_the_run(monkeypatch):
    monkeypatch.setattr(loops, "ACK_REPEAT_S", 0.0)  # a repeat at every turn of the wait
    node, hub, acks = _ended_node()
    world = hub.connect("world")
    seen: list[int] = []

    def world_ends_after_three_acks() -> None:
        for _ in range(50):  # bounded: without repeats the test fails instead of hanging
            if len(seen) == 3:
                break
            item = acks.get(0.1)
            if item is not None:
                seen.append(m.decode(m.TickAck, item.payload).tick)
        world.publisher(world.keys.end()).put(m.encode(m.RunEnd(FINAL_TICK, 7_000_000, 1, completed=(1,))))

    ending = threading.Thread(target=world_ends_after_three_acks)
    ending.start()
    loops.hand_over_end(node, threading.Event())
    ending.join()
    assert seen == [FINAL_TICK] * 3
    assert node.inbound.run_end is not None and node.inbound.run_end.completed == (1,)


def test_a_vehicle_does_not_wait_for_a_world_that_is_gone():
    node, _, acks = _ended_node()
    node.world_watch.on_token(node.bus.keys.parse(node.bus.keys.alive("world", "1")), alive=False)
    loops.hand_over_end(node, threading.Event())
    assert _acked_ticks(acks) == [FINAL_TICK]  # no repeat: it left at once


def test_a_world_that_never_ends_the_run_is_waited_for_a_bounded_time(monkeypatch, caplog):
    monkeypatch.setattr(loops, "END_WAIT_S", 0.3)
    node, _, acks = _ended_node()
    with caplog.at_level(logging.WARNING, logger="swarmloc.vehicle"):
        loops.hand_over_end(node, threading.Event())
    assert "did not end the run within 0.3 s" in caplog.text
    assert set(_acked_ticks(acks)) == {FINAL_TICK}


def test_a_vehicle_that_never_acknowledged_a_tick_has_nothing_to_hand_over():
    hub = MemoryHub()
    node = VehicleNode(hub.connect("vehicle"), SwarmConfig().for_vehicle(), 1)
    stop = threading.Event()
    loops.hand_over_end(node, stop)  # returns at once: an interrupted or never-started vehicle
    assert node.inbound.run_end is None
