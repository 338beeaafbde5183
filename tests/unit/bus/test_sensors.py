"""The sensors added by the recipe (bus.sensors) cross the bus like the built-in feeds: a batch's block
of their rows round-trips to typed messages, and any rows a peer may send decode or raise DecodeError."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus import feed
from bus.errors import DecodeError
from bus.sensors import SENSORS
from bus.sensors.compass import CompassHeading

COMPASS = next(s for s in SENSORS if s.topic == "compass")


def _batch(rows: np.ndarray, stamps: list[int]) -> bytes:
    blocks = {"compass": (np.array(stamps, dtype=np.int64), 0, rows)}
    return feed.encode_batch(feed.SensorBatch(1, 0, 1_000_000, blocks))


def test_a_compass_block_becomes_headings():
    rows = np.array([[0.5, 0.0025], [-3.0, 0.0025]])
    samples = feed.decode_batch(_batch(rows, [200_000, 400_000])).samples()
    assert [topic for topic, _ in samples] == ["compass", "compass"]
    assert samples[0][1] == CompassHeading(1, 200_000, 0, 0.5, 0.0025)


@pytest.mark.parametrize("row", [[4.0, 0.01], [0.5, 0.0], [0.5, -1.0], [np.nan, 0.01]])
def test_an_impossible_heading_is_refused_with_one_clear_error(row):
    with pytest.raises(DecodeError, match="compass"):
        feed.decode_batch(_batch(np.array([row]), [200_000]))


@given(st.lists(st.tuples(st.floats(allow_nan=True), st.floats(allow_nan=True)), min_size=1, max_size=12))
def test_any_compass_rows_decode_or_raise_decode_error(rows):
    payload = _batch(
        np.array(rows, dtype=float).reshape(-1, COMPASS.width), list(range(1000, 1000 + 1000 * len(rows), 1000))
    )
    try:
        batch = feed.decode_batch(payload)
    except DecodeError:
        return
    for _, msg in batch.samples():
        assert abs(msg.heading_rad) <= np.pi + 1e-9 and msg.variance_rad2 > 0
