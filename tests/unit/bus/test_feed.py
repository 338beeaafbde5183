"""Batched feeds and truth on the wire: round trips, a clear DecodeError for every malformed case,
and nothing but DecodeError for any bytes (hypothesis)."""

import math

import msgpack
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus import feed
from bus import messages as m
from bus.config import build_config
from bus.errors import DecodeError
from sim.world import World


def _batch(seconds: float = 0.1, vid: int = 2) -> feed.SensorBatch:
    world = World(build_config({"world": {"vehicles": 3, "seed": 4}}))
    end = round(seconds * 1e6)
    return feed.SensorBatch(vid, 1, end, world.advance(end).blocks(vid), listeners=(1, 3))


def test_round_trip_keeps_every_sample():
    batch = _batch()
    decoded = feed.decode_batch(feed.encode_batch(batch))
    assert (decoded.vehicle_id, decoded.tick, decoded.stamp_us, decoded.listeners) == (2, 1, 100_000, (1, 3))
    unaddressed = feed.SensorBatch(2, 1, 100_000, batch.blocks)
    assert feed.decode_batch(feed.encode_batch(unaddressed)).listeners is None
    samples, again = batch.samples(), decoded.samples()
    assert [t for t, _ in again] == [t for t, _ in samples] and len(samples) == 1 + 11 + 6 + 1 + 2
    for (_, a), (_, b) in zip(samples, again):
        for name in a.__dataclass_fields__:
            assert np.array_equal(np.asarray(getattr(a, name)), np.asarray(getattr(b, name)))
    stamps = [m.stamp_us for _, m in again]
    assert stamps == sorted(stamps)


def _body() -> dict:
    return msgpack.unpackb(feed.encode_batch(_batch()), raw=False)


def _rows(body: dict, topic: str, width: int) -> np.ndarray:
    return np.frombuffer(body[topic]["data"], "<f8").reshape(-1, width).copy()


def _set(body: dict, topic: str, rows: np.ndarray) -> None:
    body[topic]["data"] = rows.astype("<f8").tobytes()


def _mutate_gnss(fn):
    def mutate(body):
        rows = _rows(body, "gnss", 6)
        fn(rows)
        _set(body, "gnss", rows)

    return mutate


@pytest.mark.parametrize(
    "mutate, reason",
    [
        (lambda b: b.update(vehicle_id=0), "vehicle_id"),
        (lambda b: b.update(vehicle_id="2"), "vehicle_id"),
        (lambda b: b.update(stamp_us=-5), "stamp_us"),
        (lambda b: b.update(extra=1), "fields"),
        (lambda b: b.pop("tick"), "fields"),
        (lambda b: b.update(type="Other"), "type tag"),
        (lambda b: b["imu"].update(data=b["imu"]["data"][:-8]), "values"),
        (lambda b: b["imu"].update(stamp=b"\x00" * 7), "8-byte"),
        (lambda b: b["imu"].update(seq0=-1), "seq0"),
        (lambda b: b["imu"].pop("seq0"), "block"),
        (lambda b: b.update(imu=[1, 2, 3]), "block"),
        (lambda b: b["imu"].update(stamp=np.arange(11, dtype="<i8")[::-1].tobytes()), "ordered"),
        (lambda b: b["imu"].update(stamp=(np.arange(11, dtype="<i8") * 10_000 + 10**7).tobytes()), "inside the tick"),
        (lambda b: b["imu"].update(stamp=np.zeros(11, dtype="<i8").tobytes()), "one stamp"),
        (  # two faults: the stamps' order is said first, then the values, then two alike
            lambda b: b["imu"].update(
                stamp=np.arange(11, dtype="<i8")[::-1].tobytes(), data=np.full(66, math.nan).tobytes()
            ),
            "ordered",
        ),
        (
            lambda b: b["imu"].update(stamp=np.zeros(11, dtype="<i8").tobytes(), data=np.full(66, math.nan).tobytes()),
            "finite",
        ),
        (_mutate_gnss(lambda r: r.__setitem__((0, 0), math.nan)), "finite"),
        (_mutate_gnss(lambda r: r.__setitem__((0, 0), 1e9)), "within"),
        (_mutate_gnss(lambda r: r.__setitem__((0, slice(2, 6)), [0.0, 0.0, 0.0, 0.0])), "positive definite"),
        (_mutate_gnss(lambda r: r.__setitem__((0, slice(2, 6)), [1.0, 2.0, 2.0, 1.0])), "positive definite"),
        (_mutate_gnss(lambda r: r.__setitem__((0, slice(2, 6)), [1.0, 0.5, 0.1, 1.0])), "symmetric"),
        (lambda b: _set(b, "ranging", np.where(np.arange(7) == 0, 2.0, _rows(b, "ranging", 7))), "other vehicles"),
        (lambda b: _set(b, "ranging", np.where(np.arange(7) == 0, 2.5, _rows(b, "ranging", 7))), "other vehicles"),
        (lambda b: _set(b, "ranging", np.where(np.arange(7) == 1, -1.0, _rows(b, "ranging", 7))), "range"),
        (lambda b: _set(b, "prior", np.where(np.arange(12) == 3, -1.0, _rows(b, "prior", 12))), "positive definite"),
        (lambda b: b.update(listeners=[1, 1]), "distinct"),
        (lambda b: b.update(listeners=[2]), "own vehicle"),
        (lambda b: b.update(listeners=[0]), "listeners"),
        (lambda b: b.update(listeners=[True]), "listeners"),
        (lambda b: b.update(listeners="1"), "listeners"),
        (lambda b: b.update(listeners=list(range(1, 253))), "listeners"),
    ],
)
def test_malformed_batches_are_rejected_with_a_clear_error(mutate, reason):
    body = _body()
    mutate(body)
    with pytest.raises(DecodeError, match=reason):
        feed.decode_batch(msgpack.packb(body, use_bin_type=True))


@given(st.binary(max_size=600))
def test_garbage_bytes_raise_decode_error_only(payload):
    for decode in (feed.decode_batch, feed.decode_truth):
        try:
            decode(payload)
        except DecodeError:
            pass


PAYLOAD = feed.encode_batch(_batch())


def _mutated(payload: bytes, data) -> bytes:
    """``payload`` with one to six bytes overwritten (hypothesis draws where and what)."""
    out = bytearray(payload)
    for _ in range(data.draw(st.integers(1, 6))):
        out[data.draw(st.integers(0, len(out) - 1))] = data.draw(st.integers(0, 255))
    return bytes(out)


@given(st.data())
def test_mutated_batches_decode_or_raise_decode_error(data):
    try:
        batch = feed.decode_batch(_mutated(PAYLOAD, data))
    except DecodeError:
        return
    for _, msg in batch.samples():  # whatever passes is usable
        assert 0 <= msg.stamp_us <= batch.stamp_us


json_like = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**63), 2**64 - 1)
    | st.floats()
    | st.text(max_size=8)
    | st.binary(max_size=40),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=12,
)


@given(
    st.sampled_from(
        [
            "vehicle_id",
            "tick",
            "stamp_us",
            "imu",
            "odom",
            "gnss",
            "ranging",
            "seen",
            "landmark",
            "prior",
            "listeners",
            "x",
        ]
    ),
    json_like,
)
def test_well_formed_msgpack_with_wrong_values_raises_decode_error(field, value):
    body = _body()
    body[field] = value
    try:
        feed.decode_batch(msgpack.packb(body, use_bin_type=True))
    except DecodeError:
        pass


def test_truth_round_trip_and_rejections():
    world = World(build_config({"world": {"vehicles": 3, "seed": 4}}))
    out = world.advance(100_000)
    batch = feed.TruthBatch(1, 100_000, np.array(out.truth_stamps), np.array([1, 2, 3]), np.array(out.truth))
    again = feed.decode_truth(feed.encode_truth(batch))
    np.testing.assert_array_equal(again.rows, batch.rows)
    body = msgpack.unpackb(feed.encode_truth(batch), raw=False)
    body["ids"] = np.array([1, 1, 3], "<i8").tobytes()
    with pytest.raises(DecodeError, match="distinct"):
        feed.decode_truth(msgpack.packb(body, use_bin_type=True))


def test_the_ranging_pairs_of_a_tick_travel_with_truth_and_must_name_vehicles_of_the_batch():
    world = World(build_config({"world": {"vehicles": 3, "seed": 4}}))
    out = world.advance(1_000_000)
    ranged = out.listeners()
    pairs = np.array([(o, t) for t, observers in ranged.items() for o in observers]).reshape(-1, 2)
    assert len(pairs) > 0  # three vehicles 60 m apart range each other within a second
    batch = feed.TruthBatch(10, 1_000_000, np.array(out.truth_stamps), np.array([1, 2, 3]), np.array(out.truth), pairs)
    np.testing.assert_array_equal(feed.decode_truth(feed.encode_truth(batch)).pairs, pairs)
    body = msgpack.unpackb(feed.encode_truth(batch), raw=False)
    for bad, reason in (([1, 4], "two different vehicles"), ([2, 2], "two different vehicles"), ([1], "pairs")):
        body["pairs"] = np.array(bad, "<i8").tobytes()
        with pytest.raises(DecodeError, match=reason):
            feed.decode_truth(msgpack.packb(body, use_bin_type=True))
    del body["pairs"]
    with pytest.raises(DecodeError, match="fields must be"):
        feed.decode_truth(msgpack.packb(body, use_bin_type=True))


def _landmark_batch(rows: np.ndarray) -> bytes:
    stamps = np.arange(len(rows), dtype=np.int64) // 2 * 10_000 + 50_000  # two sightings per frame
    return feed.encode_batch(feed.SensorBatch(3, 1, 100_000, {"landmark": (stamps, 0, rows)}))


LANDMARK_ROW = [12.0, 4.5, -0.2, 0.01, 0.0, 0.0, 0.0004]


def test_landmark_sightings_round_trip_several_per_stamp():
    rows = np.array([LANDMARK_ROW, [7.0, 2.0, 0.3, 0.04, 0.0, 0.0, 0.001]] * 2)
    samples = feed.decode_batch(_landmark_batch(rows)).samples()
    assert [msg.landmark_id for _, msg in samples] == [12, 7, 12, 7] and samples[0][0] == "landmark"
    assert samples[1][1].range_m == 2.0 and np.allclose(samples[1][1].covariance, np.diag([0.04, 0.001]))


@pytest.mark.parametrize(
    "column, value, reason",
    [
        (0, 2.5, "ids must be integers"),
        (0, -1.0, "ids must be integers"),
        (0, 2e6, "within"),
        (1, -0.5, "range must be >= 0"),
        (2, 11.0, "bearing"),
        (3, -0.01, "positive definite"),
        (3, math.inf, "finite"),
    ],
)
def test_malformed_landmark_sightings_are_rejected_with_a_clear_error(column, value, reason):
    rows = np.array([LANDMARK_ROW, LANDMARK_ROW])
    rows[1, column] = value
    with pytest.raises(DecodeError, match=reason):
        feed.decode_batch(_landmark_batch(rows))


def test_truth_rows_of_nan_mean_no_truth_and_partial_nan_is_refused():
    rows = np.ones((2, 2, feed.TRUTH_WIDTH))
    rows[1, 0] = np.nan
    batch = feed.TruthBatch(1, 100_000, np.array([50_000, 100_000]), np.array([1, 2]), rows)
    assert np.isnan(feed.decode_truth(feed.encode_truth(batch)).rows[1, 0]).all()
    rows[0, 1, 2] = np.nan
    with pytest.raises(DecodeError, match="a whole row of NaN"):
        feed.decode_truth(feed.encode_truth(batch))


SEEN_ROW = [4.0, 3.2, 0.4, 0.02, 0.0, 0.0, 0.0003]  # observer 4, range, bearing, covariance (2, 2)


def _seen_batch(rows: np.ndarray) -> bytes:
    stamps = np.array([20_000, 20_000, 60_000][: len(rows)], dtype=np.int64)
    return feed.encode_batch(feed.SensorBatch(3, 1, 100_000, {"seen": (stamps, 7, rows)}))


def test_relayed_sightings_round_trip_as_seen_by():
    rows = np.array([SEEN_ROW, [1.0, 1.5, -2.0, 0.01, 0.0, 0.0, 0.001], SEEN_ROW])
    samples = feed.decode_batch(_seen_batch(rows)).samples()
    assert [topic for topic, _ in samples] == ["seen"] * 3
    first, second = samples[0][1], samples[1][1]
    assert isinstance(first, m.SeenBy) and (first.vehicle_id, first.observer_id, first.seq) == (3, 4, 7)
    assert (second.observer_id, second.range_m, second.bearing_rad, second.seq) == (1, 1.5, -2.0, 8)
    assert np.allclose(second.covariance, np.diag([0.01, 0.001]))


@pytest.mark.parametrize(
    "column, value, reason",
    [
        (0, 3.0, "observer ids must be other vehicles"),
        (0, 0.0, "observer ids"),
        (0, 251.0, "observer ids"),
        (0, 1.5, "observer ids"),
        (1, -0.5, "range must be >= 0"),
        (2, 11.0, "bearing"),
        (6, 0.0, "positive definite"),
    ],
)
def test_malformed_relayed_sightings_are_rejected_with_a_clear_error(column, value, reason):
    rows = np.array([SEEN_ROW, SEEN_ROW])
    rows[1, column] = value
    with pytest.raises(DecodeError, match=reason):
        feed.decode_batch(_seen_batch(rows))


LANDMARK_PAYLOAD = _landmark_batch(np.array([LANDMARK_ROW] * 4))
SEEN_PAYLOAD = _seen_batch(np.array([SEEN_ROW] * 3))


def _usable_sighting(msg) -> bool:
    if isinstance(msg, m.SeenBy):
        return 1 <= msg.observer_id <= 250 and msg.observer_id != msg.vehicle_id and msg.range_m >= 0
    return 0 <= msg.landmark_id <= feed.MAX_LANDMARK_ID and msg.range_m >= 0


@pytest.mark.parametrize("payload", [LANDMARK_PAYLOAD, SEEN_PAYLOAD], ids=["landmark", "seen"])
@given(data=st.data())
def test_mutated_sighting_batches_decode_or_raise_decode_error(payload, data):
    try:
        batch = feed.decode_batch(_mutated(payload, data))
    except DecodeError:
        return
    for _, msg in batch.samples():  # whatever passes is usable
        assert _usable_sighting(msg)


@pytest.mark.parametrize("topic", ["imu", "ranging"])
def test_stamps_whose_differences_overflow_are_refused(topic):
    """Order is checked by comparing stamps, never by subtracting them: 200 ms followed by a stamp
    near -2^63 has a difference that wraps to a positive int64 (hypothesis found it)."""
    width = feed.LAYOUT[topic][0]
    rows = np.zeros((2, width))
    if topic == "ranging":
        rows[:, 0], rows[:, 1], rows[:, 3], rows[:, 6] = 3, 5.0, 0.01, 1e-4
    stamps = np.array([200_000, -(2**63) + 100_000], dtype=np.int64)
    payload = feed.encode_batch(feed.SensorBatch(2, 1, 500_000, {topic: (stamps, 0, rows)}))
    with pytest.raises(DecodeError, match="stamps must be ordered"):
        feed.decode_batch(payload)
