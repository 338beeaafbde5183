"""Lockstep scoring order: metrics.csv is written in (stamp, vehicle) order however the bus
interleaves a vehicle's liveliness token with the clock and its estimates (different keys)."""

import numpy as np

from bus import feed
from bus import messages as m
from bus.config import build_config
from bus.mavlink_codec import MavlinkEncoder, StateEstimate
from bus.memory import MemoryHub
from bus.secrets import vehicle_signing_key
from bus.session import Envelope, LivelinessEvent
from groundstation.node import GroundStation

MASTER = bytes(range(32))
STEP_US = 20_000


def _frame(vid: int, t_us: int) -> bytes:
    est = StateEstimate(vid, t_us, np.array([1.0, 2.0, -30.0]), 0.0, np.zeros(3), 0.0, np.eye(6) * 0.5, np.eye(6))
    return MavlinkEncoder(vehicle_id=vid, signing_key=vehicle_signing_key(MASTER, vid)).odometry(est)


def _rows(tmp_path) -> list[tuple[float, int]]:
    lines = (tmp_path / "run" / "metrics.csv").read_text().splitlines()[1:]
    return [(float(line.split(",")[0]), int(line.split(",")[1])) for line in lines]


def test_a_late_liveliness_token_does_not_reorder_the_metrics(tmp_path):
    config = build_config({"world": {"vehicles": 2}, "clock": {"mode": "lockstep", "duration_s": 1, "tick_s": 0.02}})
    gs = GroundStation(MemoryHub().connect("groundstation"), config, tmp_path / "run", master_key=MASTER)
    keys = gs.bus.keys
    stamps = list(range(0, 6 * STEP_US, STEP_US))
    truth = feed.TruthBatch(
        0, stamps[-1], np.array(stamps), np.array([1, 2]), np.zeros((len(stamps), 2, feed.TRUTH_WIDTH))
    )
    gs.handle(Envelope(keys.truth(), feed.encode_truth(truth)))
    gs.handle(LivelinessEvent(keys.alive("vehicle", 1), True))

    def tick(k: int) -> None:
        gs.handle(Envelope(keys.clock(), m.encode(m.ClockTick(k, k * STEP_US, 0, False, (0, 0), (1, 2)))))

    tick(0)
    for t in stamps[:3]:
        gs.handle(Envelope(keys.mavlink(1), _frame(1, t)))
    tick(1)
    tick(2)  # vehicle 2 acknowledged ticks 0 and 1, but its frames and its token are still on their way
    for t in stamps[:3]:
        gs.handle(Envelope(keys.mavlink(2), _frame(2, t)))
    gs.handle(LivelinessEvent(keys.alive("vehicle", 2), True))
    tick(3)
    gs.finish("complete")
    rows = _rows(tmp_path)
    assert len(rows) == 6 and rows == sorted(rows)
