"""A block of a few rows is checked in plain Python, a larger one with numpy: both forms must give
every block the same verdict and the same message (hypothesis: stamps in and out of the tick, out
of order or alike, values beyond the limit, NaN and inf, at int64's ends; covariances at the edge of
positive definite, ids, ranges and bearings at their bounds)."""

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bus import feed_blocks as fb
from bus.errors import DecodeError
from bus.topics import Topic

STAMP_US = 3_000_000
_STAMPS = [-(2**63), 2**63 - 1, 0, 1_000_000, 1_999_999, 2_000_000, 2_000_001, 2_500_000, STAMP_US, STAMP_US + 1]
_stamps = st.lists(st.one_of(st.sampled_from(_STAMPS), st.integers(1_900_000, 3_100_000)), max_size=fb.SMALL_BLOCK_ROWS)
_SCALES = [0.0, 0.5, -0.5, 1.0, -1.0, 1.0000001, -1.0000001, float("nan"), float("inf"), -float("inf")]


@settings(max_examples=400, deadline=None)
@given(stamps=_stamps, data=st.data(), topic=st.sampled_from([Topic.IMU, Topic.ODOM, Topic.RANGING]))
def test_the_python_and_numpy_checks_agree_on_every_small_block(stamps, data, topic):
    width, _, max_abs = fb.LAYOUT[topic]
    if data.draw(st.booleans()):  # often sorted: the later checks get their turn
        stamps = sorted(stamps)
    n = len(stamps) * width  # values inside the limit, and now and then one at it or beyond it
    values = data.draw(st.lists(st.floats(-max_abs, max_abs), min_size=n, max_size=n))
    if values and data.draw(st.booleans()):
        values[data.draw(st.integers(0, n - 1))] = data.draw(st.sampled_from(_SCALES)) * max_abs
    stamp_bytes = struct.pack(f"<{len(stamps)}q", *stamps)
    data_bytes = struct.pack(f"<{len(values)}d", *values)
    rows = np.frombuffer(data_bytes, "<f8").reshape(len(stamps), width)
    once = topic not in fb.SIGHTINGS
    small = fb._flaw_small(tuple(stamps), tuple(values), STAMP_US, max_abs, once)
    numpy = fb._flaw(np.frombuffer(stamp_bytes, "<i8"), rows, STAMP_US, max_abs, once)
    assert small == numpy


def _raw(stamps: list[int], rows: np.ndarray) -> dict:
    return {"stamp": np.asarray(stamps, "<i8").tobytes(), "seq0": 0, "data": rows.astype("<f8").tobytes()}


@pytest.mark.parametrize("k", [2, fb.SMALL_BLOCK_ROWS + 2])
@pytest.mark.parametrize(
    ("stamps", "value", "reason"),
    [
        ([2_000_000, 1_900_000], 0.0, "ordered and inside the tick"),
        ([2_000_000, 3_000_001], 0.0, "ordered and inside the tick"),
        ([2_000_000, 2_100_000], float("nan"), "finite"),
        ([2_000_000, 2_000_000], 0.0, "two samples with one stamp"),
    ],
)
def test_either_form_names_the_same_fault(k, stamps, value, reason):
    """Small and large blocks: the first two stamps carry the fault, the rest are in order."""
    all_stamps = stamps + [2_500_000 + i for i in range(k - 2)]
    rows = np.zeros((k, 6))
    rows[0, 0] = value
    with pytest.raises(DecodeError, match=reason):
        fb.block(Topic.IMU, _raw(all_stamps, rows), 1, STAMP_US)


def test_a_good_block_is_its_bytes_either_way():
    for k in (3, fb.SMALL_BLOCK_ROWS + 3):
        stamps = [2_100_000 + 1000 * i for i in range(k)]
        rows = np.arange(k * 2, dtype=float).reshape(k, 2)
        got_stamps, seq0, got_rows = fb.block(Topic.ODOM, _raw(stamps, rows), 1, STAMP_US)
        assert got_stamps.tolist() == stamps and seq0 == 0 and np.array_equal(got_rows, rows)


# a row: id, range m, bearing rad, covariance (2, 2) row-major; GNSS: x m, y m, covariance (2, 2)
_EDGES = {  # a good row's column -> values at and across its bound
    "id": [0.0, 1.0, 2.0, 3.0, 17.0, 250.0, 251.0, 1.5, -1.0, 999_999.0, 1_000_000.0],
    "range": [0.0, -0.0, -1e-9, 1e-9],
    "bearing": [10.0, -10.0, math.nextafter(10.0, 11.0), -math.nextafter(10.0, 11.0)],
    "a": [0.0, -0.0, 1e-300, -1e-300],
    "c": ["b(1+1e-9)", "b(1+2e-9)", "b+1e-300"],  # the symmetry test's tolerance, relative to b
    "det": ["singular"],  # a d == b c exactly
}


def _good_row(draw, topic) -> list[float]:
    a, d = draw(st.floats(0.01, 5.0)), draw(st.floats(0.01, 5.0))
    b = draw(st.floats(-0.9, 0.9)) * math.sqrt(a * d)
    head = [draw(st.floats(-100, 100)), draw(st.floats(-100, 100))]
    if topic is not Topic.GNSS:
        head = [float(draw(st.integers(0 if topic is Topic.LANDMARK else 1, 30))), 5.0, 0.3]
    return [*head, a, b, b, d]


def _spoiled(row: list[float], column: str, edge, topic) -> list[float]:
    row = list(row)
    a_at, b_at = len(row) - 4, len(row) - 3
    if column == "c":
        b = row[b_at]
        row[b_at + 1] = {"b(1+1e-9)": b * (1 + 1e-9), "b(1+2e-9)": b * (1 + 2e-9), "b+1e-300": b + 1e-300}[edge]
    elif column == "det":
        row[a_at : a_at + 4] = [1.0, 2.0, 2.0, 4.0]
    elif column == "a":
        row[a_at] = edge
    elif topic is not Topic.GNSS:
        row[{"id": 0, "range": 1, "bearing": 2}[column]] = edge
    return row


@st.composite
def _rows(draw, topic):
    rows = [_good_row(draw, topic) for _ in range(draw(st.integers(0, fb.SMALL_BLOCK_ROWS)))]
    if rows and draw(st.integers(0, 3)):  # mostly: one entry of one row at or across its bound
        column = draw(st.sampled_from(sorted(_EDGES)))
        i = draw(st.integers(0, len(rows) - 1))
        rows[i] = _spoiled(rows[i], column, draw(st.sampled_from(_EDGES[column])), topic)
    return rows


@settings(max_examples=2000, deadline=None)
@given(data=st.data(), topic=st.sampled_from([Topic.GNSS, Topic.RANGING, Topic.SEEN, Topic.LANDMARK]))
def test_the_python_and_numpy_topic_checks_agree_on_every_small_block(data, topic):
    rows = data.draw(_rows(topic))
    width = fb.LAYOUT[topic][0]
    array = np.array(rows, dtype=float).reshape(len(rows), width)
    values = tuple(array.ravel().tolist())
    vehicle_id = data.draw(st.sampled_from([1, 3, 17]))
    assert fb._topic_flaw_small(topic, values, width, vehicle_id) == fb._topic_flaw(topic, array, vehicle_id)
