"""A lockstep tick's acknowledgement waits (bounded) for the previous tick's estimates and truth, so
that they are scored and on disk before the world moves on: zenoh orders one key, not keys, and a
ground station that acknowledged a tick before its vehicles' frames of the tick before came, and was
killed then, lost them too. The monotonic clock is injected: the rule, not a timing."""

import queue

import numpy as np

from bus import feed
from bus import messages as m
from bus.config import build_config
from bus.mavlink_codec import MavlinkEncoder, StateEstimate
from bus.memory import MemoryHub
from bus.session import Envelope
from groundstation import node as node_module
from groundstation.node import GroundStation
from groundstation.tick_ack import ACK_HOLD_S

TICK_US = 1_000_000
VEHICLES = (1, 2)


def _frame(encoder: MavlinkEncoder, vid: int, t_us: int) -> bytes:
    est = StateEstimate(vid, t_us, np.array([1.0, 2.0, -30.0]), 0.0, np.zeros(3), 0.0, np.eye(6) * 0.5, np.eye(6))
    return encoder.odometry(est)


def test_a_tick_is_acknowledged_once_the_tick_before_is_scored_or_the_hold_is_over(tmp_path, monkeypatch):
    now = [50.0]
    monkeypatch.setattr(node_module.time, "monotonic", lambda: now[0])
    config = build_config(
        {"world": {"vehicles": 2}, "clock": {"mode": "lockstep", "duration_s": 10}, "view": {"record": False}}
    )
    hub, inbox = MemoryHub(), queue.SimpleQueue()
    gs = GroundStation(hub.connect("groundstation"), config, tmp_path / "run")
    hub.connect("world").subscribe(gs.bus.keys.ack("gs"), inbox, 1 << 10)
    keys, encoders = gs.bus.keys, {vid: MavlinkEncoder(vehicle_id=vid) for vid in VEHICLES}
    period_us = round(1e6 / config.vehicle.mavlink_rate_hz)

    def acknowledged() -> list[int]:
        gs.ack_if_drained()
        return [m.decode(m.GroundStationAck, inbox.get().payload).tick for _ in range(inbox.qsize())]

    def tick(k: int) -> None:
        gs.handle(
            Envelope(
                keys.clock(), m.encode(m.ClockTick(k, k * TICK_US, 0, False, (0, 0), VEHICLES, VEHICLES if k else ()))
            )
        )

    def truth(k: int) -> None:
        stamps = np.arange((k - 1) * TICK_US + period_us, k * TICK_US + 1, period_us) if k else np.array([0])
        batch = feed.TruthBatch(
            k, k * TICK_US, stamps, np.array(VEHICLES), np.zeros((len(stamps), 2, feed.TRUTH_WIDTH))
        )
        gs.handle(Envelope(keys.truth(), feed.encode_truth(batch)))

    def frames(vid: int, k: int) -> None:
        for t in range((k - 1) * TICK_US + period_us if k else 0, k * TICK_US + 1, period_us):
            gs.handle(Envelope(keys.mavlink(vid), _frame(encoders[vid], vid, t)))

    def scored_until_s() -> float:
        gs.run.flush()
        lines = (tmp_path / "run" / "metrics.csv").read_text().splitlines()[1:]
        return max((float(line.split(",")[0]) for line in lines), default=-1.0)

    truth(0)
    tick(0)
    assert acknowledged() == [0]  # nothing before the first tick
    frames(1, 0)
    frames(2, 0)
    tick(1)
    assert acknowledged() == [1] and scored_until_s() == 0.0
    tick(2)
    frames(1, 1)
    assert acknowledged() == []  # vehicle 2's frames of tick 1 are still on their way
    frames(2, 1)
    assert acknowledged() == []  # and tick 1's truth
    truth(1)
    assert acknowledged() == [2] and scored_until_s() == 1.0
    truth(2)
    tick(3)  # vehicle 2's frames of tick 2 never come: the tick goes on once the hold is over
    frames(1, 2)
    now[0] += ACK_HOLD_S - 0.01
    assert acknowledged() == []
    now[0] += 0.02
    assert acknowledged() == [3]
    truth(3)
    tick(4)  # vehicle 2 stopped short of the tick acknowledged before (a restart): not waited for
    frames(1, 3)
    assert acknowledged() == [4]
    gs.finish("complete")
