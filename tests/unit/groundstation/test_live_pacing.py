"""A lockstep run with a paced live view (`view.live_speed`): the ground station holds each tick's
acknowledgement until the wall clock has caught up with the sim time at that many times real time,
so the world cannot run ahead of a viewer. The wall clock is injected: the rule, not a timing."""

import queue
import socket

import numpy as np

from bus import feed
from bus import messages as m
from bus.config import build_config
from bus.mavlink_codec import MavlinkEncoder, StateEstimate
from bus.memory import MemoryHub
from bus.session import Envelope
from groundstation import node as node_module
from groundstation.node import GroundStation


def test_a_paced_live_view_holds_each_ack_until_the_wall_clock_catches_up(tmp_path, monkeypatch):
    wall = [100.0]
    monkeypatch.setattr(node_module.time, "perf_counter", lambda: wall[0])
    config = build_config(
        {
            "world": {"vehicles": 1},
            "clock": {"mode": "lockstep", "duration_s": 10},
            "view": {"live": True, "live_speed": 2.0, "record": False, "live_port": _free_port()},
        }
    )
    hub = MemoryHub()
    inbox: queue.SimpleQueue = queue.SimpleQueue()
    watcher = hub.connect("world")
    gs = GroundStation(hub.connect("groundstation"), config, tmp_path / "run")
    watcher.subscribe(gs.bus.keys.ack("gs"), inbox, 1 << 10)
    acks: list[int] = []

    def acknowledged() -> list[int]:
        while not inbox.empty():
            acks.append(m.decode(m.GroundStationAck, inbox.get().payload).tick)
        return acks

    tick_us = round(config.clock.tick_s * 1e6)

    def tick(k: int) -> None:
        gs.handle(
            Envelope(
                gs.bus.keys.clock(), m.encode(m.ClockTick(k, k * tick_us, 0, False, (0,), (1,), (1,) if k else ()))
            )
        )
        gs.ack_if_drained()

    tick(0)  # the run starts: nothing ahead yet
    assert acknowledged() == [0]
    # tick 0's truth and estimate are in (a tick's acknowledgement also waits for the tick before's)
    truth = feed.TruthBatch(0, 0, np.array([0]), np.array([1]), np.zeros((1, 1, feed.TRUTH_WIDTH)))
    gs.handle(Envelope(gs.bus.keys.truth(), feed.encode_truth(truth)))
    est = StateEstimate(1, 0, np.array([1.0, 2.0, -30.0]), 0.0, np.zeros(3), 0.0, np.eye(6) * 0.5, np.eye(6))
    gs.handle(Envelope(gs.bus.keys.mavlink(1), MavlinkEncoder(vehicle_id=1).odometry(est)))
    tick(1)  # one tick of sim at 2x real time wants half a tick of wall; none has passed
    assert acknowledged() == [0]
    wall[0] += config.clock.tick_s / 2.0 - 0.01
    gs.ack_if_drained()
    assert acknowledged() == [0]
    wall[0] += 0.02
    gs.ack_if_drained()
    assert acknowledged() == [0, 1]
    gs.finish("complete")


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]
