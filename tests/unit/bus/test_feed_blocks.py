"""A block of a few rows is checked in plain Python, a larger one with numpy: both forms must give
every block the same verdict and the same message (hypothesis: stamps in and out of the tick, out
of order or alike, values beyond the limit, NaN and inf, at int64's ends)."""

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
    small = fb._flaw_small(stamp_bytes, data_bytes, STAMP_US, max_abs, once)
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
