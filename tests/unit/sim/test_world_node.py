"""The world node survives anything on the keys it listens to (acks, liveliness, the fault plan):
counted by reason, never fatal; an ack counts only for the vehicle whose key it came on."""

import queue

from hypothesis import given, settings
from hypothesis import strategies as st

from bus import messages as m
from bus.config import build_config
from bus.memory import MemoryHub
from bus.rejections import counts_to_dict
from bus.session import Envelope, LivelinessEvent
from sim.node import WorldNode


def _world() -> WorldNode:
    return WorldNode(MemoryHub().connect("world"), build_config({"world": {"vehicles": 3}}))


def test_hostile_acks_tokens_and_plans_are_counted_and_never_count_for_anyone():
    node = _world()
    keys = node.bus.keys
    for vid in (1, 2, 3):
        node.intake.handle(LivelinessEvent(keys.alive("vehicle", vid), True), None)
    for item in (
        LivelinessEvent("swarm/alive/vehicle/\u00b2", True),
        LivelinessEvent("swarm/alive/vehicle/0", True),
        Envelope("swarm/ctl/ack/x", b"1"),
        Envelope(keys.ack(2), b"garbage"),
        Envelope(keys.ack(2), m.encode(m.TickAck(1, 0))),  # vehicle 2 acking for vehicle 1
        Envelope(keys.ack(9), m.encode(m.TickAck(9, 0))),  # not in the swarm
        Envelope(keys.fault_plan(), b"{}"),
        Envelope(keys.ack("gs"), b"junk"),
    ):
        node.intake.handle(item, 0)
    assert counts_to_dict(node.rejections.as_counts()) == {
        "bad_key": 3,
        "malformed": 3,
        "impersonation": 1,
        "unknown_vehicle": 1,
    }
    assert node.members.alive == {1, 2, 3} and node.members.acked == set()
    node.intake.handle(Envelope(keys.ack(1), m.encode(m.TickAck(1, 0, 4))), 0)
    assert node.members.acked == {1} and node.members.v2v_published(3) == (4, 0, 0)


@settings(max_examples=200)
@given(st.binary(max_size=300), st.text(max_size=8))
def test_any_bytes_on_any_ack_key_are_never_fatal(payload, ident):
    node = _world()
    node.intake.handle(Envelope(f"swarm/ctl/ack/{ident}", payload), 0)
    node.intake.handle(Envelope("swarm/ctl/ack/1", payload), 0)
    node.intake.handle(Envelope("swarm/ctl/faults/plan", payload), 0)
    node.intake.handle(LivelinessEvent(f"swarm/alive/{ident}/{ident}", True), 0)


def test_a_restarted_vehicle_keeps_its_broadcast_count_growing():
    node = _world()
    node.members.on_v2v_count(2, 30)
    node.members.on_v2v_count(2, 5)  # restarted: counts from zero again
    assert node.members.v2v_published(3) == (0, 35, 0)


def test_a_vehicle_that_leaves_before_its_final_ack_arrives_still_completed_the_run():
    """Ack and departure travel on different keys and may arrive in either order."""
    import threading

    node = _world()
    keys = node.bus.keys
    for vid in (1, 2, 3):
        node.intake.handle(LivelinessEvent(keys.alive("vehicle", vid), True), None)
    finishing = set(node.members.alive)
    node.members.acked = set()
    for vid in (1, 2, 3):
        node.intake.mailbox.lanes[0].put(LivelinessEvent(keys.alive("vehicle", vid), False))  # gone first
    acks = node.intake.mailbox.lanes[1]
    late = threading.Timer(
        0.3, lambda: [acks.put(Envelope(keys.ack(vid), m.encode(m.TickAck(vid, 7)))) for vid in (1, 2, 3)]
    )  # the acks after
    late.start()
    node.await_final_acks(7, finishing, threading.Event(), timeout_s=5.0)
    late.join()
    assert node.members.acked == {1, 2, 3}


def test_a_restarted_vehicle_that_acks_an_older_tick_is_waited_for_until_it_catches_up():
    """A restarted process starts slower than the swarm: its first ack is for a tick the world has
    already left. It joins lockstep all the same, and the next ticks wait for it (a vehicle that
    joined only with an ack of the current tick could fall behind for good on a fast machine)."""
    node = _world()
    keys = node.bus.keys
    for vid in (1, 2, 3):
        node.intake.handle(LivelinessEvent(keys.alive("vehicle", vid), True), None)
    node.members.started = True  # the run is at tick 31
    node.intake.handle(LivelinessEvent(keys.alive("vehicle", 2), False), None)  # killed
    node.intake.handle(LivelinessEvent(keys.alive("vehicle", 2), True), None)  # restarted
    assert node.members.alive == {1, 3} and node.members.joining == {2}
    node.members.acked = set()
    behind = Envelope(keys.ack(2), m.encode(m.TickAck(2, 29)))  # tick 29 while the world is at 31
    node.intake.handle(behind, 31)
    assert node.members.alive == {1, 2, 3} and node.members.acked == set()
    for vid in (1, 3):
        node.intake.handle(Envelope(keys.ack(vid), m.encode(m.TickAck(vid, 31))), 31)
    assert not node.members.alive <= node.members.acked  # the clock waits for vehicle 2
    node.intake.handle(Envelope(keys.ack(2), m.encode(m.TickAck(2, 31))), 31)
    assert node.members.alive <= node.members.acked


def test_a_realtime_world_paces_its_vehicles_with_the_ticks_they_need_and_tells_the_ground_station_every_one():
    hub = MemoryHub()
    config = build_config({"world": {"vehicles": 2}, "clock": {"mode": "realtime", "duration_s": 2.5}})
    node = WorldNode(hub.connect("world"), config)
    keys, listener = node.bus.keys, hub.connect("listener")
    clock, pace = queue.SimpleQueue(), queue.SimpleQueue()
    listener.subscribe(keys.clock(), clock, 1 << 16)
    listener.subscribe(keys.pace(), pace, 1 << 16)
    for tick in range(node.final_tick + 1):
        node.send(node.prepare(tick), final=tick == node.final_tick)

    def heard(q: queue.SimpleQueue) -> list[int]:
        ticks = []
        while not q.empty():
            ticks.append(m.decode(m.ClockTick, q.get().payload).tick)
        return ticks

    assert heard(clock) == list(range(126))
    assert heard(pace) == [0, 1, 50, 100, 125]


def test_the_start_goes_on_while_processes_keep_joining():
    """250 processes starting on two cores join over minutes: the deadline counts from the last join."""
    from sim.node import JoinDeadline

    start = JoinDeadline(60.0, now=0.0)
    assert not start.expired(1, now=50.0)  # one joined at 50 s: the start may go on until 110 s
    assert not start.expired(1, now=109.0) and not start.expired(2, now=109.5)
    assert not start.expired(2, now=169.0)
    assert start.expired(2, now=170.0)  # nobody new for 60 s


def test_the_start_ends_when_nobody_joins():
    from sim.node import JoinDeadline

    start = JoinDeadline(60.0, now=0.0)
    assert not start.expired(0, now=59.9) and start.expired(0, now=60.1)


def test_a_vehicle_whose_token_comes_back_before_the_first_tick_is_a_member_again():
    """250 vehicles starting on two cores: a session that misses its lease loses its token and declares
    it again; before the run began it missed nothing and must not be kept waiting for an ack."""
    from sim.membership import Membership

    members = Membership(expected={1, 2})
    members.on_token("groundstation", None, True)
    for vid in (1, 2):
        members.on_token("vehicle", vid, True)
    members.on_token("vehicle", 2, False)
    assert not members.everyone_joined()
    members.on_token("vehicle", 2, True)
    assert members.everyone_joined()


def test_a_vehicle_back_after_the_first_tick_joins_with_its_first_ack():
    from sim.membership import Membership

    members = Membership(expected={1, 2}, started=True)
    members.on_token("vehicle", 2, True)
    members.on_token("vehicle", 2, False)
    members.on_token("vehicle", 2, True)
    assert 2 in members.joining and 2 not in members.alive
