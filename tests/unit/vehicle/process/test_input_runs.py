"""A batch's IMU and wheel samples reach the filter as runs (vehicle.process.input_runs): in exactly the order,
and with exactly the result, that one message at a time gives, through late samples, replays from
checkpoints, a batch that comes after its cycles and a batch that comes twice."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bus import feed
from bus.config import build_config
from sim.world import World
from vehicle.estimators import ekf
from vehicle.process.fusion import FusionHorizon
from vehicle.process.input_runs import INPUT_TOPICS, unpack
from vehicle.process.sequence import SequenceTracker

PERIOD_US = 20_000


class _Recorded:
    """A filter that notes every sample it takes: (stamp, topic), whichever way it came."""

    def __init__(self) -> None:
        self.f = ekf.build(vehicle_id=1, spec=build_config({}).sensors, gate_probability=0.9995)
        self.taken: list[tuple[int, str]] = []

    def handle(self, msg) -> None:
        self.taken.append((msg.stamp_us, type(msg).__name__))
        self.f.handle(msg)

    def handle_row(self, topic, stamp_us, row, message) -> None:
        self.taken.append((stamp_us, {"imu": "ImuSample", "odom": "WheelOdometry"}[topic]))
        self.f.handle_row(topic, stamp_us, row, message)

    def __getattr__(self, name: str):  # cycle, snapshot, restore: the filter's own
        return getattr(self.f, name)


def _batches(seconds: int) -> list[feed.SensorBatch]:
    """Vehicle 1's batches, one a second, through the wire format (its ranging left out: no neighbours)."""
    world, out = World(build_config({"world": {"vehicles": 2, "seed": 6}})), []
    for k in range(seconds + 1):
        batch = feed.SensorBatch(1, k, k * 1_000_000, world.advance(k * 1_000_000).blocks(1))
        batch = feed.decode_batch(feed.encode_batch(batch))
        out.append(feed.SensorBatch(1, k, batch.stamp_us, {t: b for t, b in batch.blocks.items() if t != "ranging"}))
    return out


def _push(fusion: FusionHorizon, batch: feed.SensorBatch, as_runs: bool, late_gnss: list) -> None:
    """One batch, as runs (vehicle.process.input_runs.unpack) or one message at a time in its order
    (``SensorBatch.samples``); its GNSS fixes held back into ``late_gnss``."""
    first = fusion.reserve(batch.count())
    if as_runs:
        run, others = unpack(batch, first)
        if run is not None:
            fusion.push_run(run)
    else:
        others = [(first + place, topic, msg) for place, (topic, msg) in enumerate(batch.samples())]
    for arrival, topic, msg in others:
        if topic == "gnss":
            late_gnss.append((msg.stamp_us + 70_000, topic, msg, arrival))
        else:
            fusion.push(topic, msg, arrival)


def _fly(as_runs: bool, *, every_cycles: int, late_batch: int | None = None, twice: int | None = None):
    """Cycle every 20 ms over 5 s; batch k comes at k s (batch ``late_batch`` 60 ms after its first
    cycle ran, batch ``twice`` a second time), every GNSS fix 70 ms late."""
    est = _Recorded()
    fusion = FusionHorizon(est, horizon_us=500_000, every_cycles=every_cycles)
    ahead = 1_000_000  # a batch covers the second before its stamp: it comes before those cycles
    waiting, late_gnss = [(b.stamp_us - ahead + (60_000 if b.tick == late_batch else 0), b) for b in _batches(5)], []
    waiting += [(b.stamp_us - ahead + 30_000, b) for b in _batches(5) if b.tick == twice]
    waiting.sort(key=lambda item: item[0])
    for t in range(0, 5_000_001, PERIOD_US):
        while waiting and waiting[0][0] <= t:
            _push(fusion, waiting.pop(0)[1], as_runs, late_gnss)
        for item in [g for g in late_gnss if g[0] <= t]:
            late_gnss.remove(item)
            fusion.push(item[1], item[2], item[3])
        fusion.cycle(t)
    return est, fusion


@pytest.mark.parametrize(
    "case",
    [
        {"every_cycles": 5},
        {"every_cycles": 1, "late_batch": 2},
        {"every_cycles": 5, "twice": 3},
    ],
    ids=["late fixes replayed", "a batch after its cycles", "a batch twice"],
)
def test_runs_give_what_one_message_at_a_time_gives(case):
    runs, fusion_runs = _fly(True, **case)
    messages, fusion_messages = _fly(False, **case)
    assert fusion_messages.counters.replays >= 10  # the late fixes replayed run samples
    assert runs.taken == messages.taken  # the same samples in the same order, replays included
    assert np.array_equal(runs.f.state.x, messages.f.state.x) and np.array_equal(runs.f.state.P, messages.f.state.P)
    assert fusion_runs.counters == fusion_messages.counters
    if "twice" in case:
        assert fusion_runs.counters.duplicates > 100


def test_a_range_of_sequence_numbers_counts_as_one_by_one():
    rng = np.random.default_rng(2)
    ranged, single = SequenceTracker(), SequenceTracker()
    seq = 0
    for _ in range(400):
        seq += int(rng.integers(-30, 60))  # gaps, repeats and steps back
        count = int(rng.integers(0, 120))
        ranged.see_range("imu", seq, count)
        for s in range(seq, seq + count):
            single.see("imu", s)
    assert (ranged.lost, ranged.received("imu")) == (single.lost, single.received("imu"))
    assert ranged._recent == single._recent


def test_a_batch_makes_one_run_in_its_order_or_none_without_input_samples():
    """Both input topics in one run, each sample in its place in the batch's order; a batch whose IMU
    and wheels were blacked out for the whole tick (empty blocks) gives no run, and one sample one."""
    batch = _batches(1)[1]
    run, others = unpack(batch, 100)
    topics = [topic for topic, _ in run.idents]
    order = [(topic, msg.stamp_us) for topic, msg in batch.samples()]
    assert [(t, s) for t, s in zip(topics, run.stamps)] == [p for p in order if p[0] in ("imu", "odom")]
    assert (
        run.arrivals == sorted(run.arrivals) and [100 + order.index(p) for p in zip(topics, run.stamps)] == run.arrivals
    )
    assert {t for t, _, _ in run.blocks} == {"imu", "odom"} and len(run.stamps) + len(others) == batch.count()
    empty = {
        t: (s[:0], seq0, rows[:0]) if t in ("imu", "odom") else (s, seq0, rows)
        for t, (s, seq0, rows) in batch.blocks.items()
    }
    assert unpack(feed.SensorBatch(1, 1, batch.stamp_us, empty), 0)[0] is None
    one = {
        t: (s[:1], seq0, rows[:1]) if t == "imu" else (s[:0], seq0, rows[:0])
        for t, (s, seq0, rows) in batch.blocks.items()
    }
    single, _ = unpack(feed.SensorBatch(1, 1, batch.stamp_us, one), 0)
    assert single.idents == [("imu", batch.blocks["imu"][1])]
    made = [run.message(i) for i in range(len(run.stamps))]  # the rare path's messages, sample by sample
    assert [(type(m).__name__, m.stamp_us, m.seq) for m in made] == [
        ({"imu": "ImuSample", "odom": "WheelOdometry"}[topic], stamp, seq)
        for (topic, seq), stamp in zip(run.idents, run.stamps)
    ]


@st.composite
def _any_batch(draw) -> feed.SensorBatch:
    """A batch of any of the feed's topics (rows of their widths), stamps drawn from a few values so
    that topics share stamps (sightings several per stamp), and now and then camera frames."""
    blocks = {}
    for topic in draw(st.lists(st.sampled_from(feed.TOPICS), unique=True, max_size=5)):
        width = feed.LAYOUT[topic][0]
        stamps = draw(st.lists(st.integers(0, 40), max_size=12, unique=topic not in feed.SIGHTINGS))
        seq0 = draw(st.integers(0, 1000))
        rows = np.arange(len(stamps) * width, dtype=float).reshape(len(stamps), width) + seq0
        blocks[topic] = (np.array(sorted(stamps), np.int64), seq0, rows)
    camera = None
    frames = draw(st.lists(st.integers(0, 40), max_size=3, unique=True))
    if frames:
        k = len(frames)
        camera = feed.CameraBlock(np.array(sorted(frames), np.int64), 7, np.ones(k), np.zeros((k, 8, 8), np.uint8))
    return feed.SensorBatch(1, 0, 40, blocks, camera)


def _described(msg) -> tuple:
    return (type(msg).__name__, msg.stamp_us, msg.seq)


@settings(max_examples=300, deadline=None)
@given(_any_batch(), st.integers(0, 10**6))
def test_unpack_keeps_the_batch_order_of_every_sample(batch, first):
    """Input samples in the run and the others as messages, each numbered by its place in
    ``SensorBatch.samples``' order (stamp, then topic order, camera frames last): whatever the topics,
    shared stamps and block sizes."""
    run, others = unpack(batch, first)
    expected = [(first + place, topic, msg) for place, (topic, msg) in enumerate(batch.samples())]
    inputs = [(arrival, topic, msg) for arrival, topic, msg in expected if topic in INPUT_TOPICS]
    assert [(a, t, _described(msg)) for a, t, msg in others] == [
        (a, t, _described(msg)) for a, t, msg in expected if t not in INPUT_TOPICS
    ]
    if not inputs:
        assert run is None
        return
    assert run.arrivals == [a for a, _, _ in inputs]
    assert run.stamps == [msg.stamp_us for _, _, msg in inputs]
    assert run.idents == [(t, msg.seq) for _, t, msg in inputs]
    assert run.rows == [batch.blocks[t][2][msg.seq - batch.blocks[t][1]].tolist() for _, t, msg in inputs]
    assert [_described(run.message(i)) for i in range(len(inputs))] == [_described(msg) for _, _, msg in inputs]
    assert run.blocks == [(t, seq0, len(s)) for t, (s, seq0, _) in batch.blocks.items() if t in INPUT_TOPICS]
