"""The vehicle node over the in-memory bus: anything on any key it listens to is counted by reason,
never fatal; cycles follow the loop rate; a lockstep tick waits for its batch and its neighbours'
broadcasts; its subscriptions never reach truth; its config carries nothing that determines truth."""

import queue

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus import feed
from bus import messages as m
from bus.config import SwarmConfig, build_config
from bus.mailbox import Oversized
from bus.mavlink_codec import MavlinkDecoder, MavlinkEncoder, StateEstimate, StatusText, split_frames
from bus.memory import MemoryHub
from bus.rejections import counts_to_dict
from bus.session import Envelope, LivelinessEvent
from vehicle.process.node import VehicleNode


def _node(vid: int = 1, config: dict | None = None) -> tuple[VehicleNode, MemoryHub]:
    """A vehicle node on an in-memory bus, of the default swarm or of ``config`` (build_config's input)."""
    hub = MemoryHub()
    swarm = SwarmConfig() if config is None else build_config(config)
    return VehicleNode(hub.connect("vehicle"), swarm.for_vehicle(), vid), hub


REALTIME = {"clock": {"mode": "realtime"}}


def _batch(vid: int, tick: int, stamp_us: int, blocks: dict) -> bytes:
    return feed.encode_batch(feed.SensorBatch(vid, tick, stamp_us, blocks))


PRIOR = {"prior": (np.array([0]), 0, np.concatenate([np.zeros(3), np.eye(3).ravel()])[None])}


def _estimate(vid: int, t_us: int, cov: np.ndarray | None = None) -> StateEstimate:
    return StateEstimate(
        vid, t_us, np.array([1.0, 2.0, -30.0]), 0.0, np.zeros(3), 0.0, np.eye(6) if cov is None else cov, np.eye(6)
    )


def test_garbage_on_every_key_is_counted_by_reason_and_the_node_keeps_working():
    node, _ = _node()
    keys = node.bus.keys
    items = [
        Envelope(keys.feed(1), b"\xc1garbage"),
        Envelope(keys.clock(), b"\x00"),
        Envelope(keys.fault_plan(), b"{"),
        Envelope(keys.end(), b"\x93\x01"),
        Envelope("swarm/v/x/v2v", b"anything"),
        Envelope("swarm/v/\u00b2/v2v", b"x"),
        Envelope("swarm/v/9/v2v", b"x"),
        Envelope(keys.v2v(2), b"not mavlink"),
        Envelope(keys.feed(1), _batch(2, 0, 0, PRIOR)),
        Envelope(keys.v2v(2), MavlinkEncoder(vehicle_id=3).odometry(_estimate(3, 0))),
        Envelope(keys.v2v(3), MavlinkEncoder(vehicle_id=3).heartbeat()),
        Oversized(keys.v2v(2), 10**6),
        None,
    ]
    for item in items:
        assert node.take(item) is None
    assert counts_to_dict(node.rejections.as_counts()) == {
        "malformed": 5,
        "bad_key": 2,
        "unknown_vehicle": 1,
        "impersonation": 2,
        "unexpected": 1,
        "oversized": 1,
    }
    node.take(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    node.cycle(0)
    assert node.estimator.initialized


@given(st.binary(max_size=300), st.sampled_from(["feed", "v2v", "mavlink", "status"]), st.text(max_size=6))
def test_any_bytes_on_any_key_are_counted_never_raised(payload, topic, ident):
    node, _ = _node()
    before = node.rejections.total
    for key in (
        f"swarm/v/{ident}/{topic}",
        "swarm/v/1/feed",
        "swarm/ctl/clock",
        "swarm/ctl/pace",
        "swarm/ctl/end",
        "swarm/v/2/v2v",
        "swarm/v/2/v2v/1",
        f"swarm/v/2/v2v/{ident}",
    ):
        result = node.take(Envelope(key, payload))
        assert result is None or isinstance(result, m.ClockTick)
    assert node.rejections.total >= before


def test_neighbour_estimates_with_degenerate_covariances_are_refused_when_used():
    node, _ = _node()
    for k, cov in enumerate((np.zeros((6, 6)), np.diag([1.0, -1.0, 1, 1, 1, 1]), np.diag([1e12, 1.0, 1, 1, 1, 1]))):
        epoch = 200_000 * (k + 1)
        node.v2v.hear(2, epoch, MavlinkEncoder(vehicle_id=2).odometry(_estimate(2, epoch, cov)))
        node.v2v.hold(m.RangeBearing(1, epoch, k, 2, 5.0, 0.0, np.diag([0.01, 1e-4])))
    assert node.rejections.total == 0  # kept, not decoded: no measurement needed them yet
    assert node.v2v.mature(10**6) == [] and node.v2v.missing == 3
    assert counts_to_dict(node.rejections.as_counts()) == {"degenerate": 3}


def test_cycles_follow_the_loop_rate_in_sim_time():
    node, _ = _node()
    assert node.cycles_due(0) == [0]
    assert node.cycles_due(100_000) == [20_000, 40_000, 60_000, 80_000, 100_000]
    assert node.cycles_due(100_000) == []


def test_a_tick_waits_for_its_batch_and_for_every_broadcast_the_neighbours_sent():
    node, _ = _node()
    keys = node.bus.keys
    node.take(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    first = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, 0, False))))
    assert node.waits.ready(first)
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(1, 100_000, 0, False, (0, 2, 1)))))
    assert not node.waits.ready(tick)  # batch 1 still on its way
    node.take(Envelope(keys.feed(1), _batch(1, 1, 100_000, {})))
    assert not node.waits.ready(tick)  # vehicle 2 sent two broadcasts, vehicle 3 one
    for vid, t in ((2, 0), (2, 200_000), (3, 0)):
        node.take(Envelope(keys.v2v(vid), MavlinkEncoder(vehicle_id=vid).odometry(_estimate(vid, t))))
    assert node.waits.ready(tick)


def test_a_tick_whose_batch_was_refused_runs_without_it_and_only_that_tick():
    """The world sends one batch per tick, in order: a refused one (malformed, too large) was the next
    tick's, which then runs at once without it; the tick after still waits for its own."""
    node, _ = _node()
    keys = node.bus.keys
    node.take(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, 0, False))))
    node.finish_tick(tick)
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(1, 100_000, 0, False))))
    assert not node.waits.ready(tick)  # batch 1 on its way
    node.take(Envelope(keys.feed(1), b"\x93not a batch"))
    assert node.waits.ready(tick)  # it came, refused: nothing more is coming for tick 1
    node.finish_tick(tick)
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(2, 200_000, 0, False))))
    assert not node.waits.ready(tick)  # batch 2 is its own
    node.take(Oversized(keys.feed(1), 10**7))
    assert node.waits.ready(tick)
    node.finish_tick(tick)
    node.take(Envelope(keys.feed(1), _batch(1, 3, 300_000, {})))
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(3, 300_000, 0, False))))
    assert node.waits.ready(tick) and node.inbound.refused_since == 0
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(4, 400_000, 0, False))))
    assert not node.waits.ready(tick)
    assert counts_to_dict(node.rejections.as_counts()) == {"malformed": 1, "oversized": 1}


def _ranging(vid: int, stamps_us: list[int], targets: list[int]) -> dict:
    rows = np.array([[j, 10.0, 0.1, 0.09, 0.0, 0.0, 0.0004] for j in targets])
    return {"ranging": (np.array(stamps_us), 0, rows)}


def test_a_cycle_inside_a_long_tick_waits_for_the_broadcasts_its_ranging_pairs_with():
    """A tick of 0.5 s spans several V2V latencies: the cycle at t + latency waits for the neighbour's
    broadcast of t when that neighbour runs the whole tick, and not otherwise."""
    node, _ = _node()
    keys = node.bus.keys
    node.take(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    first = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, 0, False, (), (1, 2, 3), (1, 2, 3)))))
    for t in node.cycles_due(first.stamp_us):
        node.cycle(t)
    node.finish_tick(first)
    node.take(Envelope(keys.feed(1), _batch(1, 1, 500_000, _ranging(1, [200_000, 200_000], [2, 3]))))
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(1, 500_000, 0, False, (), (1, 2, 3), (1, 2)))))
    assert node.waits.ready(tick)
    assert node.waits.unheard_neighbours(tick, 280_000) == []  # not matured yet
    assert node.waits.unheard_neighbours(tick, 300_000) == [(2, 200_000)]  # 3 is rejoining: not waited for
    node.take(Envelope(keys.v2v(2), MavlinkEncoder(vehicle_id=2).no_estimate(200_000)))
    assert node.waits.unheard_neighbours(tick, 300_000) == []
    assert node.rejections.total == 0  # "no estimate" is a broadcast, not a fault


def test_a_cycle_waits_for_a_broadcast_of_the_previous_tick_from_a_neighbour_that_ran_it():
    """Frames go only to the vehicles that range their sender, so no count of broadcasts covers a fix
    stamped in the previous tick that matures in this one: the cycle waits for its frame if the
    neighbour ran that tick, and not for a neighbour that did not (it was rejoining)."""
    node, _ = _node()
    keys = node.bus.keys
    node.take(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    first = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, 0, False, (), (1, 2, 3), (1, 2, 3)))))
    node.finish_tick(first)
    node.take(Envelope(keys.feed(1), _batch(1, 1, 400_000, _ranging(1, [400_000, 400_000], [2, 3]))))
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(1, 400_000, 0, False, (), (1, 2, 3), (1, 2)))))
    assert node.waits.unheard_neighbours(tick, 400_000) == []  # matures at 500 ms, in the next tick
    node.finish_tick(tick)
    node.take(Envelope(keys.feed(1), _batch(1, 2, 800_000, {})))
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(2, 800_000, 0, False, (), (1, 2, 3), (1, 2, 3)))))
    assert node.waits.ready(tick)  # nothing was broadcast to everyone: no count to wait for
    assert node.waits.unheard_neighbours(tick, 500_000) == [(2, 400_000)]  # 3 did not run tick 1
    node.take(Envelope(keys.v2v_to(2, 1), MavlinkEncoder(vehicle_id=2).odometry(_estimate(2, 400_000))))
    assert node.waits.unheard_neighbours(tick, 500_000) == []


def test_a_neighbour_that_died_is_not_waited_for():
    node, _ = _node()
    keys = node.bus.keys
    node.take(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    first = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, 0, False, (), (1, 2), (1, 2)))))
    node.finish_tick(first)
    node.take(Envelope(keys.feed(1), _batch(1, 1, 500_000, _ranging(1, [200_000], [2]))))
    tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(1, 500_000, 0, False, (), (1, 2), (1, 2)))))
    assert node.waits.unheard_neighbours(tick, 300_000) == [(2, 200_000)]
    node.take(LivelinessEvent(keys.alive("vehicle", 2), alive=False))
    assert node.waits.unheard_neighbours(tick, 300_000) == []


def test_vehicle_subscriptions_never_reach_truth():
    hub = MemoryHub()
    VehicleNode(hub.connect("vehicle"), SwarmConfig().for_vehicle(), 2)
    subscribed = [expr for expr, _, _ in hub._subscriptions]
    assert subscribed and not any(hub.connect("vehicle").keys.is_truth(e) for e in subscribed)


def test_a_vehicle_config_carries_nothing_that_determines_truth():
    """Swarms that differ in everything that makes truth (world seed, trajectories, layout, speed)
    give their vehicles byte-identical configs: a vehicle cannot rebuild the world from its own."""
    a = build_config({"world": {"seed": 1, "trajectories": ["circle"], "radius_m": 20.0, "spacing_m": 60.0}})
    b = build_config(
        {
            "world": {
                "seed": 987654,
                "trajectories": ["waypoints", "figure8"],
                "radius_m": 35.0,
                "spacing_m": 90.0,
                "speed_mps": 6.0,
            }
        }
    )
    assert a.for_vehicle().model_dump_json() == b.for_vehicle().model_dump_json()
    dumped = a.for_vehicle().model_dump()
    assert "world" not in dumped and "seed" not in str(dumped).replace("fault_seed", "")
    from sim.world import World

    with pytest.raises(AttributeError):
        World(a.for_vehicle())  # the world needs what a vehicle is never given


def test_divergence_guard_resets_instead_of_publishing_nan():
    node, hub = _node()
    out: queue.SimpleQueue = queue.SimpleQueue()
    hub.connect("groundstation").subscribe(node.bus.keys.mavlink(1), out)
    node.take(Envelope(node.bus.keys.feed(1), _batch(1, 0, 0, PRIOR)))
    node.cycle(0)
    node.estimator.P[0, 0] = np.nan  # a numerical accident inside the filter
    for t_us in range(20_000, 100_001, 20_000):  # to the next estimate sent (10 Hz)
        node.cycle(t_us)
    node.outbound.flush()
    decoder, decoded = MavlinkDecoder(), []
    while not out.empty():
        decoded += [decoder.decode(f) for f in split_frames(out.get().payload)[0]]
    estimates = [d for d in decoded if isinstance(d, StateEstimate)]
    assert [e.reset_counter for e in estimates] == [0, 1]
    assert np.all(np.isfinite(estimates[-1].pose_covariance)) and np.all(np.isfinite(estimates[-1].position_m))
    assert any(isinstance(d, StatusText) and d.text.startswith("estimator reset") for d in decoded)


def test_a_vehicle_whose_world_is_gone_stops_with_a_clear_error(monkeypatch):
    import vehicle.process.world_watch as world_watch
    from bus.session import LivelinessEvent

    node, _ = _node()
    node.world_watch.timeout_s = 5.0
    clock = [100.0]
    monkeypatch.setattr(world_watch.time, "monotonic", lambda: clock[0])
    node.take(LivelinessEvent("swarm/alive/world/0", True))
    node.take(LivelinessEvent("swarm/alive/world/0", False))
    clock[0] += 4.0
    node.world_watch.check()  # not yet
    clock[0] += 2.0
    with pytest.raises(world_watch.WorldGone, match="gone for 5 s"):
        node.world_watch.check()


@pytest.mark.parametrize("mode", ["realtime", "lockstep"])
def test_v2v_frames_go_to_the_listeners_the_batch_names_else_to_everyone(mode: str):
    """A simulation's batch names who ranges the vehicle: its epoch's V2V frame goes to each of them
    on its own key; with no batch naming them (the first cycle, replays) it is broadcast. A frame
    addressed to another vehicle is refused; lockstep's barrier counts only what was broadcast."""
    hub = MemoryHub()
    sent: list[str] = []
    deliver = hub.deliver
    hub.deliver = lambda key, payload: (sent.append(key), deliver(key, payload))
    node = VehicleNode(hub.connect("vehicle"), build_config({"clock": {"mode": mode}}).for_vehicle(), 1)
    keys = node.bus.keys
    for tick, listeners in enumerate([(), (3, 4), (), ()]):  # batches for stamps 0, 20, 40, 60 ms
        blocks = PRIOR if tick == 0 else {}
        node.take(
            Envelope(
                keys.feed(1), feed.encode_batch(feed.SensorBatch(1, tick, tick * 20_000, blocks, listeners=listeners))
            )
        )
    assert node.inbound.listeners_at(0) is None and node.inbound.listeners_at(20_000) == (3, 4)
    assert node.inbound.listeners_at(40_000) == () and node.inbound.listeners_at(80_000) is None
    node.cycle(0)  # a V2V epoch (every 200 ms) with no batch before the first: broadcast
    node.outbound.cycle(200_000, node.estimator, 0, listeners=(3, 4))
    node.outbound.cycle(400_000, node.estimator, 0, listeners=())  # nobody ranges it: nothing sent
    v2v = [key for key in sent if "/v2v" in key]
    assert v2v == [keys.v2v(1), keys.v2v_to(1, 3), keys.v2v_to(1, 4)]
    frame = MavlinkEncoder(vehicle_id=2).odometry(_estimate(2, 0))
    assert node.take(Envelope(keys.v2v_to(2, 5), frame)) is None
    assert counts_to_dict(node.rejections.as_counts()) == {"unexpected": 1}
    node.take(Envelope(keys.v2v_to(2, 1), frame))
    assert node.inbound.heard_until == {2: 0} and node.inbound.heard == {}
    node.take(Envelope(keys.v2v(2), MavlinkEncoder(vehicle_id=2).odometry(_estimate(2, 200_000))))
    assert node.inbound.heard_until == {2: 200_000} and node.inbound.heard == {2: 1}


@pytest.mark.parametrize("mode", ["realtime", "lockstep"])
def test_realtime_an_epochs_addressed_frames_go_at_the_vehicles_turn_as_they_were_at_the_epoch(mode: str):
    """Vehicle 3's turn is 40 ms after the epoch in realtime (``send_turn_us``): its epoch's frames go
    to the listeners then, before that cycle's own, the bytes fixed at the epoch; held frames go at the
    run's end; lockstep sends them at the epoch."""
    hub = MemoryHub()
    sent: list[tuple[str, bytes]] = []
    deliver = hub.deliver
    hub.deliver = lambda key, payload: (sent.append((key, payload)), deliver(key, payload))
    node = VehicleNode(hub.connect("vehicle"), build_config({"clock": {"mode": mode}}).for_vehicle(), 3)
    node.take(Envelope(node.bus.keys.feed(3), _batch(3, 0, 0, PRIOR)))
    node.cycle(0)
    to_1 = node.bus.keys.v2v_to(3, 1)

    def frames_to_1() -> list[bytes]:
        return [payload for key, payload in sent if key == to_1]

    node.outbound.cycle(200_000, node.estimator, 0, listeners=(1,))
    at_epoch = frames_to_1()
    for t_us in (220_000, 240_000):
        node.outbound.cycle(t_us, node.estimator, 0)
        if t_us == 220_000:
            before_turn = frames_to_1()
    node.outbound.cycle(400_000, node.estimator, 0, listeners=(1,))
    node.outbound.send_held()
    if mode == "lockstep":
        assert len(at_epoch) == 1 and len(frames_to_1()) == 2
        return
    assert at_epoch == [] and before_turn == []
    first, last = frames_to_1()
    assert [MavlinkDecoder().decode(split_frames(f)[0][0]).time_usec for f in (first, last)] == [200_000, 400_000]


def test_realtime_a_flood_of_messages_delays_filing_never_a_cycle():
    """Realtime: a cycle that is due runs before the loop files what is queued (a flood on the
    neighbours' lane is filed between cycles, one item at a time)."""
    import threading
    import time as wall

    from vehicle.process.loops import run_realtime

    node, hub = _node(1, REALTIME)
    keys = node.bus.keys
    world, neighbours = node.mailbox.lanes
    long_ago = wall.time_ns() - 10**9
    world.put(Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, long_ago, False))))
    world.put(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    world.put(Envelope(keys.clock(), m.encode(m.ClockTick(1, 20_000, long_ago, False))))  # cycle 1 is long due
    for _ in range(5000):
        neighbours.put(Envelope(keys.v2v(2), b"junk"))
    stop, queued_at_due_cycle = threading.Event(), []
    cycle = node.cycle

    def due_cycle(t_us: int) -> None:
        if t_us > 0:  # the first cycle has no deadline
            queued_at_due_cycle.append(len(neighbours.items))
            stop.set()
        cycle(t_us)

    node.cycle = due_cycle
    run_realtime(node, stop)
    # none of the junk filed (the first cycle's own broadcast may be queued too)
    assert len(queued_at_due_cycle) == 1 and queued_at_due_cycle[0] >= 5000


def test_realtime_the_first_cycle_runs_on_the_first_tick_and_is_acknowledged():
    """Realtime: the run's first cycle runs as soon as the world's first tick and its batch are in,
    whatever the tick's wall time, counts no jitter, and is acknowledged (the world starts its clock
    then: sim.node); the cycles after it wait for the next tick."""
    import threading
    import time as wall

    from vehicle.process.loops import run_realtime

    node, hub = _node(1, REALTIME)
    keys = node.bus.keys
    acks = queue.Queue()
    hub.add_subscription(keys.ack(1), acks)
    node.world_lane.put(Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, wall.time_ns(), False))))
    node.world_lane.put(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    stop = threading.Event()
    loop = threading.Thread(target=run_realtime, args=(node, stop))
    loop.start()
    ack = m.decode(m.TickAck, acks.get(timeout=10).payload)
    stop.set()
    loop.join()
    assert ack.tick == 0 and node.stats.cycles == 1 and node.estimator.initialized
    assert node.stats.jitter_p99_us() == 0.0  # no jitter sample: the ring is empty


def test_realtime_a_cycle_is_due_the_feed_lead_and_its_phase_after_the_worlds_tick():
    """Realtime: the vehicle's cycle at the stamp of the world's first paced tick (the second) is due
    ``realtime.feed_lead_s`` after the tick's wall time, plus the vehicle's phase of the period, and
    never runs before (a tick sent 0.1 s ago, a lead of 0.3 s)."""
    import threading
    import time as wall

    from vehicle.process.loops import run_realtime, schedule_phase_s

    lead_s = 0.3
    node, _ = _node(1, {"clock": {"mode": "realtime"}, "vehicle": {"realtime": {"feed_lead_s": lead_s}}})
    keys = node.bus.keys
    world, _neighbours = node.mailbox.lanes
    due_ns = wall.time_ns() - 100_000_000
    world.put(Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, due_ns - 20_000_000, False))))
    world.put(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    world.put(Envelope(keys.clock(), m.encode(m.ClockTick(1, 20_000, due_ns, False))))
    world.put(Envelope(keys.feed(1), _batch(1, 1, 20_000, {})))
    stop, cycled_at = threading.Event(), []
    cycle = node.cycle

    def paced_cycle(t_us: int) -> None:
        if t_us > 0:
            cycled_at.append(wall.time_ns())
            stop.set()
        cycle(t_us)

    node.cycle = paced_cycle
    run_realtime(node, stop)
    phase_s = schedule_phase_s(1, node.config.vehicles, node.period_us * 1e-6)
    assert cycled_at and cycled_at[0] >= due_ns + round((lead_s + phase_s) * 1e9)


def test_realtime_the_final_tick_ends_the_loop_after_the_cycles_up_to_its_stamp():
    """Realtime: the final clock tick can overtake the last sensor batch (different keys); the loop
    still runs its cycles up to the final stamp, with that batch, before its final status and ack."""
    import threading
    import time as wall

    from vehicle.process.loops import run_realtime

    node, hub = _node(1, REALTIME)
    keys = node.bus.keys
    acks = queue.Queue()
    hub.add_subscription(keys.ack(1), acks)
    world = node.mailbox.lanes[0]
    for item in (
        Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, wall.time_ns(), False))),
        Envelope(keys.clock(), m.encode(m.ClockTick(1, 20_000, wall.time_ns(), True))),  # before the batches
        Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)),
        Envelope(keys.feed(1), _batch(1, 1, 20_000, {})),
    ):
        world.put(item)
    run_realtime(node, threading.Event())
    assert node.stats.cycles == 2 and node.estimator.initialized and node.estimator.state.time_us == 20_000
    assert [m.decode(m.TickAck, acks.get_nowait().payload).tick for _ in range(2)] == [0, 1]  # the first, the final


def test_realtime_a_late_loop_files_the_queued_batches_before_cycling():
    """Realtime, far behind schedule: the batches already queued are filed before each cycle runs
    (no cycle runs blind with its data in the mailbox, to be fused late by a replay after)."""
    import threading
    import time as wall

    from vehicle.process.loops import run_realtime

    node, hub = _node(1, REALTIME)
    keys = node.bus.keys
    long_ago = wall.time_ns() - 10**9  # every deadline of this run is past
    for item in (
        Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, long_ago, False))),
        Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)),
        Envelope(keys.feed(1), _batch(1, 1, 20_000, {})),
        Envelope(keys.clock(), m.encode(m.ClockTick(1, 20_000, long_ago, True))),
    ):
        node.world_lane.put(item)
    run_realtime(node, threading.Event())
    assert node.stats.cycles == 2 and node.estimator.state.time_us == 20_000
    assert node.fusion.counters.replays == 0 and node.fusion.counters.dropped_stale == 0


def test_a_lying_vehicle_changes_only_its_v2v_broadcast_and_signs_it_as_itself():
    """The ``lie`` fault in the plan: vehicle 1's V2V frames carry its position moved by the lie's
    offset and its covariance scaled, signed with its own key; its MAVLink stream to the ground
    station stays honest; before the lie starts and after it ends, V2V is honest too."""
    from bus.mavlink_codec import MavlinkDecoder, pose_of, split_frames

    hub = MemoryHub()
    sent: list[tuple[str, bytes]] = []
    deliver = hub.deliver
    hub.deliver = lambda key, payload: (sent.append((key, payload)), deliver(key, payload))
    lie = {"kind": "lie", "vehicle": 1, "offset_m": [30.0, -30.0], "cov_scale": 0.01, "start_s": 0.2, "for_s": 0.2}
    config = build_config({"faults": [lie]}).for_vehicle()
    node = VehicleNode(hub.connect("vehicle"), config, 1, signing_key=bytes(32))
    keys = node.bus.keys
    decoder, gs_decoder = MavlinkDecoder(signing_key=bytes(32)), MavlinkDecoder(signing_key=bytes(32))
    node.take(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
    for t_us in (0, 200_000, 400_000):  # V2V epochs: before, during and after the lie
        node.cycle(t_us)
        node.outbound.flush()
    v2v = [pose_of(decoder.decode(p)) for k, p in sent if k == keys.v2v(1)]
    gs = [
        pose_of(e)
        for k, p in sent
        if k == keys.mavlink(1)
        for f in split_frames(p)[0]
        if isinstance(e := gs_decoder.decode(f), StateEstimate)
    ]
    honest = {round(e.stamp_us): e for e in gs}
    assert [e.stamp_us for e in v2v] == [0, 200_000, 400_000]
    for e in v2v:
        offset = e.pose[:2] - honest[e.stamp_us].pose[:2]
        scale = e.pose_cov[0, 0] / honest[e.stamp_us].pose_cov[0, 0]
        if e.stamp_us == 200_000:
            np.testing.assert_allclose(offset, [30.0, -30.0], atol=1e-3)
            assert scale == pytest.approx(0.01, rel=1e-4)
        else:
            np.testing.assert_allclose(offset, [0.0, 0.0], atol=1e-9)
            assert scale == pytest.approx(1.0)


def test_lockstep_a_status_counts_the_cycle_it_follows():
    """The periodic status goes out after its cycle's statistics are recorded, so the last one of a run
    says what the final status says: a ground station that keeps either writes the same summary."""
    import threading
    import time as wall

    from vehicle.process.loops import run_lockstep

    node, hub = _node(1, {"world": {"vehicles": 1}})
    keys = node.bus.keys
    statuses = queue.Queue()
    hub.add_subscription(keys.status(1), statuses)
    world = node.mailbox.lanes[0]
    for item in (
        Envelope(keys.clock(), m.encode(m.ClockTick(0, 0, wall.time_ns(), False))),
        Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)),
        Envelope(keys.feed(1), _batch(1, 1, 20_000, {})),
        Envelope(keys.clock(), m.encode(m.ClockTick(1, 20_000, wall.time_ns(), False))),
        Envelope(keys.clock(), m.encode(m.ClockTick(2, 20_000, wall.time_ns(), True))),
    ):
        world.put(item)
    run_lockstep(node, threading.Event())
    sent = [m.decode(m.VehicleStatus, statuses.get_nowait().payload) for _ in range(statuses.qsize())]
    periodic, final = [s for s in sent if not s.final], [s for s in sent if s.final]
    assert [(s.stamp_us, s.cycles) for s in periodic] == [(0, 1)]  # the cycle at 0 s counted
    assert [(s.stamp_us, s.cycles) for s in final] == [(20_000, 2)] and node.stats.cycles == 2


def test_realtime_vehicles_take_turns_to_fuse_an_epoch_and_lockstep_ones_do_not():
    """Realtime: vehicle i fuses an epoch's fixes its turn of loop cycles after the V2V wait, the turns
    over the first half of the V2V period (its next broadcast still carries them) and inside the
    fusion horizon; lockstep: every vehicle right after the wait. Schedules in loop cycles."""
    config = SwarmConfig()
    wait_us, cycle_us = round(config.vehicle.cooperation.latency_s * 1e6), round(1e6 / config.vehicle.loop_rate_hz)

    def turns(swarm: dict | None) -> list[float]:
        return [(_node(vid, swarm)[0].v2v.latency_us - wait_us) / cycle_us for vid in range(1, 7)]

    assert turns(None) == [0] * 6
    assert turns(REALTIME) == [0, 1, 2, 3, 4, 0]  # 5 cycles of 50 Hz in half of the 0.2 s V2V period
    narrow = {**REALTIME, "vehicle": {"fusion_horizon_s": 0.15}}  # room for 2 turns beyond the wait
    assert turns(narrow) == [0, 1, 0, 1, 0, 1]


def test_lockstep_cycles_a_waiting_fix_will_revise_run_once_and_send_the_same():
    """A lockstep cycle whose estimate a ranging fix still waiting for its neighbour's broadcast will
    revise, and that sends nothing on a schedule, runs with the next cycle that does, and the fix is
    fused right after the cycle at its stamp (which broadcast without it): the MAVLink stream is the
    same to the byte as with every cycle run at once and replayed, and no cycle runs twice."""
    sent, cycles = {}, {}
    for deferrable in (False, True):
        node, hub = _node(1, {"world": {"vehicles": 2}})
        keys = node.bus.keys
        mavlink = queue.Queue()
        hub.add_subscription(keys.mavlink(1), mavlink)
        estimator, runs = node.estimator, []
        inner = estimator.cycle
        estimator.cycle = lambda t_us: (runs.append(t_us), inner(t_us))
        node.take(Envelope(keys.feed(1), _batch(1, 0, 0, PRIOR)))
        seen = np.array([[2, np.hypot(1.0, 2.0) + 0.05, np.arctan2(2.0, 1.0) - 0.02, 0.09, 0.0, 0.0, 0.0004]] * 2)
        ranging = {"ranging": (np.array([200_000, 600_000]), 0, seen)}  # the neighbour as _estimate puts it
        node.take(Envelope(keys.feed(1), _batch(1, 1, 1_000_000, ranging)))
        for stamp in (200_000, 600_000):
            node.take(Envelope(keys.v2v(2), MavlinkEncoder(vehicle_id=2).odometry(_estimate(2, stamp))))
        for number, stamp in enumerate((0, 1_000_000)):
            tick = node.take(Envelope(keys.clock(), m.encode(m.ClockTick(number, stamp, 0, number == 1))))
            for t in node.cycles_due(tick.stamp_us):
                node.cycle(t, deferrable=deferrable and t < tick.stamp_us)
                node.report(t)
            node.finish_tick(tick)
        assert node.estimator.counters.v2v_fused == 2 and node.fusion.counters.late_fused == 2
        sent[deferrable] = [mavlink.get_nowait().payload for _ in range(mavlink.qsize())]
        cycles[deferrable] = runs
    assert sent[True] == sent[False] and len(sent[True]) == 2
    assert sorted(set(cycles[True])) == sorted(set(cycles[False])) == list(range(0, 1_000_001, 20_000))
    # run at once, each fix replays at least its stamp's cycle and the 4 after it (from the checkpoint
    # the horizon keeps: in lockstep none is kept just before a fix, vehicle.process.node._deliver)
    assert len(cycles[False]) >= 51 + 2 * 5
    assert len(cycles[True]) == 51  # the 4 after it waited for the fix, which came right after its own


@pytest.mark.parametrize(
    "config, kept",
    [
        (None, False),
        (REALTIME, True),
        ({"faults": [{"kind": "loss", "percent": 10.0, "start_s": 0.0}]}, True),
    ],
    ids=["lockstep", "realtime", "lockstep with a link fault"],
)
def test_a_checkpoint_waits_for_a_ranging_fix_only_where_it_can_come_after_its_cycles(config, kept):
    """A ranging measurement held for its neighbour's broadcast asks the fusion horizon for a
    checkpoint just before it where the fix can come after later cycles ran (realtime, link faults);
    in lockstep a cycle waits for that broadcast first, so none is kept."""
    node, _ = _node(config=config)
    node.take(Envelope(node.bus.keys.feed(1), _batch(1, 0, 0, PRIOR)))
    node.take(Envelope(node.bus.keys.feed(1), _batch(1, 1, 1_000_000, _ranging(1, [200_000], [2]))))
    assert (200_000 in node.fusion._expected) is kept
