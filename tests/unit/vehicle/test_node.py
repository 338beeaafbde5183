"""The vehicle node over the in-memory bus: garbage is counted, never fatal; cycles at a fixed rate."""


import numpy as np

from bus import messages as m
from bus.config import SwarmConfig
from bus.memory import MemoryHub
from bus.session import Envelope
from vehicle.node import VehicleNode


def _node() -> tuple[VehicleNode, MemoryHub]:
    hub = MemoryHub()
    return VehicleNode(hub.connect("vehicle"), SwarmConfig(), 1), hub


def test_garbage_on_every_feed_is_counted_and_the_node_keeps_working():
    node, _ = _node()
    for topic in ("imu", "odom", "gnss", "prior"):
        assert node.take(Envelope(node.bus.keys.sensor(1, topic), b"\xc1garbage")) is None
    assert node.take(Envelope(node.bus.keys.clock(), b"\x00")) is None
    assert node.decode_errors == 5
    prior = m.PosePrior(1, 0, 0, np.zeros(3), np.eye(3))
    node.take(Envelope(node.bus.keys.sensor(1, "prior"), m.encode(prior)))
    node.cycle(0)
    assert node.estimator.initialized


def test_cycles_follow_the_loop_rate_in_sim_time():
    node, _ = _node()
    assert node.cycles_due(0) == [0]
    assert node.cycles_due(100_000) == [20_000, 40_000, 60_000, 80_000, 100_000]
    assert node.cycles_due(100_000) == []


def test_feeds_complete_needs_every_sample_up_to_the_tick():
    node, _ = _node()
    keys = node.bus.keys
    node.take(Envelope(keys.sensor(1, "prior"), m.encode(m.PosePrior(1, 0, 0, np.zeros(3), np.eye(3)))))
    for seq, t in enumerate((0, 10_000, 20_000)):
        node.take(Envelope(keys.sensor(1, "imu"), m.encode(m.ImuSample(1, t, seq, np.zeros(3), np.zeros(3)))))
    node.take(Envelope(keys.sensor(1, "gnss"), m.encode(m.GnssFix(1, 0, 0, np.zeros(2), np.eye(2)))))
    node.take(Envelope(keys.sensor(1, "odom"), m.encode(m.WheelOdometry(1, 0, 0, 1.0, 0.0))))
    tick = m.ClockTick(1, 20_000, 0, False, (1, 3, 2, 1, 0, 1, 3, 2, 1, 0))  # vehicles 1, 2: prior, imu, odom, gnss, ranging
    assert not node.feeds_complete(tick)  # odometry of 20 ms still on its way
    node.take(Envelope(keys.sensor(1, "odom"), m.encode(m.WheelOdometry(1, 20_000, 1, 1.0, 0.0))))
    assert node.feeds_complete(tick)
    jammed = m.ClockTick(2, 40_000, 0, False, (1, 3, 2, 1, 0))  # a silenced feed publishes nothing more
    assert node.feeds_complete(jammed)


def test_vehicle_subscriptions_never_reach_truth():
    hub = MemoryHub()
    VehicleNode(hub.connect("vehicle"), SwarmConfig(), 2)
    subscribed = [expr for expr, _ in hub._subscriptions]
    assert subscribed and not any(hub.connect("vehicle").keys.is_truth(e) for e in subscribed)


def test_divergence_guard_resets_instead_of_publishing_nan():
    import queue

    from bus.mavlink_codec import MavlinkDecoder, StateEstimate, StatusText

    node, hub = _node()
    out: queue.SimpleQueue = queue.SimpleQueue()
    hub.connect("groundstation").subscribe(node.bus.keys.mavlink(1), out)
    node.take(Envelope(node.bus.keys.sensor(1, "prior"), m.encode(m.PosePrior(1, 0, 0, np.zeros(3), np.eye(3)))))
    node.cycle(0)
    node.estimator.P[0, 0] = np.nan  # a numerical accident inside the filter
    node.cycle(20_000)
    decoder, decoded = MavlinkDecoder(), []
    while not out.empty():
        decoded.append(decoder.decode(out.get().payload))
    estimates = [d for d in decoded if isinstance(d, StateEstimate)]
    assert [e.reset_counter for e in estimates] == [0, 1]
    assert np.all(np.isfinite(estimates[-1].pose_covariance)) and np.all(np.isfinite(estimates[-1].position_m))
    assert any(isinstance(d, StatusText) and d.text.startswith("estimator reset") for d in decoded)
