"""The ground station survives anything on any key it listens to: bad keys, garbage, oversized
payloads, degenerate signed frames, far-off stamps, unknown sysids, impersonation. Each is counted
by reason and never scored; genuine estimates still are."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bus import feed
from bus import messages as m
from bus.config import build_config
from bus.mailbox import Oversized
from bus.mavlink_codec import MavlinkEncoder, StateEstimate
from bus.memory import MemoryHub
from bus.rejections import counts_to_dict
from bus.secrets import vehicle_signing_key
from bus.session import Envelope, LivelinessEvent, Request
from groundstation.node import GroundStation

MASTER = bytes(range(32))


def _gs(tmp_path) -> GroundStation:
    config = build_config({"world": {"vehicles": 3}, "clock": {"duration_s": 10}})
    return GroundStation(MemoryHub().connect("groundstation"), config, tmp_path / "run", master_key=MASTER)


def _estimate(vid: int, t_us: int, cov=None, x: float = 1.0) -> StateEstimate:
    return StateEstimate(
        vid, t_us, np.array([x, 2.0, -30.0]), 0.0, np.zeros(3), 0.0, np.eye(6) * 0.5 if cov is None else cov, np.eye(6)
    )


def _frame(vid: int, t_us: int, key_of: int | None = None, **kw) -> bytes:
    key = vehicle_signing_key(MASTER, key_of or vid)
    return MavlinkEncoder(vehicle_id=vid, signing_key=key).odometry(_estimate(vid, t_us, **kw))


def _truth(gs: GroundStation, stamps: list[int]) -> None:
    rows = np.zeros((len(stamps), 3, feed.TRUTH_WIDTH))
    batch = feed.TruthBatch(0, stamps[-1], np.array(stamps), np.array([1, 2, 3]), rows)
    gs.handle(Envelope(gs.bus.keys.truth(), feed.encode_truth(batch)))


def test_hostile_input_is_counted_by_reason_and_only_genuine_estimates_are_scored(tmp_path):
    gs = _gs(tmp_path)
    keys = gs.bus.keys
    _truth(gs, [0, 20_000, 40_000])
    answers = []
    hostile = [
        Envelope("swarm/v/x/mavlink", b"bytes"),
        Envelope("swarm/v/\u00b2/mavlink", b"bytes"),
        Envelope("swarm/v/9/mavlink", _frame(9, 0)),  # not in the swarm
        Envelope(keys.mavlink(2), b"garbage"),  # not MAVLink
        Envelope(keys.mavlink(2), _frame(2, 20_000, cov=np.zeros((6, 6)))),  # zero covariance, signed
        Envelope(keys.mavlink(2), _frame(3, 20_000)),  # vehicle 3's frame on 2's key
        Envelope(keys.mavlink(2), _frame(2, 20_000, key_of=1)),  # signed with vehicle 1's key
        Envelope(keys.mavlink(2), _frame(2, 3_000_000_000)),  # far future (sim time 0)
        Envelope(keys.mavlink(2), MavlinkEncoder(vehicle_id=2).odometry(_estimate(2, 20_000))),  # unsigned
        Envelope(keys.status(2), m.encode(m.VehicleStatus(3, 0, 1, 0, 0.0, 0.0, 0, 0, 0, 0))),  # status as 3
        Envelope(keys.status(1), b"\x00"),
        Envelope(keys.truth(), b"\x93"),
        Envelope(keys.clock(), b"x"),
        Envelope(keys.end(), b"\x01\x02"),
        Oversized(keys.mavlink(1), 10**7),
        LivelinessEvent("swarm/alive/vehicle/\u00b2", True),
        LivelinessEvent("swarm/alive/vehicle/77", True),
        Request(keys.claim(), b"{not json", answers.append),
        Request(keys.fault_request(), b"\xff" * 40, answers.append),
    ]
    for item in hostile:
        gs.handle(item)
    for t in (0, 20_000, 40_000):
        gs.handle(Envelope(keys.mavlink(2), _frame(2, t)))  # the genuine stream, after all of that
    gs.scorer.release(float("inf"))
    assert counts_to_dict(gs.rejections.as_counts()) == {
        "bad_key": 3,
        "unknown_vehicle": 2,
        "malformed": 7,
        "degenerate": 1,
        "impersonation": 2,
        "bad_signature": 1,
        "stamp_out_of_range": 1,
        "unsigned": 1,
        "oversized": 1,
    }
    assert gs.scorer.tallies[2].samples == 3 and set(gs.scorer.tallies) == {2}
    assert len(answers) == 2 and all(b'"ok":false' in a for a in answers)
    assert gs.ended is None  # garbage on the end key did not end the run


@settings(max_examples=150)
@given(st.binary(max_size=400), st.sampled_from(["mavlink", "status", "feed", "v2v"]), st.text(max_size=5))
def test_any_bytes_on_any_key_are_never_fatal(tmp_path_factory, payload, topic, ident):
    gs = _gs(tmp_path_factory.mktemp("gs"))
    for key in (f"swarm/v/{ident}/{topic}", "swarm/v/1/mavlink", "swarm/truth", "swarm/ctl/clock", "swarm/ctl/end"):
        gs.handle(Envelope(key, payload))
    gs.handle(Request("swarm/ctl/claim", payload, lambda reply: None))
    gs.handle(Request("swarm/ctl/faults/request", payload, lambda reply: None))
    gs.handle(LivelinessEvent(f"swarm/alive/vehicle/{ident}", True))
    gs.run.close()


def test_the_realtime_live_table_shows_a_running_ground_station(tmp_path):
    """`swarm up --mode realtime` without --quiet redraws the RMSE table every half second from the
    running ground station (it once called an attribute the station no longer had, and died)."""
    from groundstation.display import live_display

    gs = _gs(tmp_path)
    _truth(gs, [0, 500_000])
    gs.handle(Envelope(gs.bus.keys.mavlink(1), _frame(1, 500_000)))
    gs.handle(Envelope(gs.bus.keys.clock(), m.encode(m.ClockTick(25, 500_000, 0, False))))
    assert gs.sim_time_us == 500_000
    with live_display("realtime", 10.0, quiet=False) as on_progress:
        on_progress(gs)


def test_what_a_vehicle_says_is_stamped_with_when_it_said_it(tmp_path):
    """A STATUSTEXT and the events it announces take the SYSTEM_TIME sent just before it, not the
    ground station's clock tick (which trails by up to a tick and depends on arrival order); without
    one, or with one far from the swarm's time, the tick."""
    import json

    gs = _gs(tmp_path)
    keys = gs.bus.keys
    gs.handle(Envelope(keys.clock(), m.encode(m.ClockTick(2, 1_000_000, 0, False))))
    encoder = MavlinkEncoder(vehicle_id=2, signing_key=vehicle_signing_key(MASTER, 2))
    said = [
        encoder.system_time(760_000) + encoder.statustext(4, "distrust v3: 8 of 8 fixes fail the gate"),
        encoder.statustext(4, "trust v3: consistent again"),  # no SYSTEM_TIME before it
        encoder.system_time(900_000_000) + encoder.statustext(6, "far off"),  # 15 min ahead of the swarm
    ]
    for payload in said:
        gs.handle(Envelope(keys.mavlink(2), payload))
    gs.run.flush()
    events = [json.loads(line) for line in (tmp_path / "run" / "events.jsonl").read_text().splitlines()]
    stamps = {(e["event"], e.get("text", e.get("reason"))): e["t_s"] for e in events if e.get("vehicle") == 2}
    assert stamps[("neighbour_distrusted", "8 of 8 fixes fail the gate")] == 0.76
    assert stamps[("vehicle_message", "distrust v3: 8 of 8 fixes fail the gate")] == 0.76
    assert stamps[("neighbour_trusted", "consistent again")] == 1.0
    assert stamps[("vehicle_message", "far off")] == 1.0
    assert gs.rejections.total == 0


@given(st.integers(0, 2**32 - 1), st.integers(0, 2**50))
def test_a_system_time_is_read_near_the_swarms_time_or_not_at_all(time_boot_ms, now_us):
    from groundstation.mavlink_in import FUTURE_US, PAST_US, said_at

    stamp = said_at(time_boot_ms, now_us)
    assert stamp is None or (now_us - PAST_US <= stamp <= now_us + FUTURE_US and stamp // 1000 % 2**32 == time_boot_ms)
    assert said_at((now_us // 1000) % 2**32, now_us) == now_us // 1000 * 1000  # its own time, past any wrap
