"""The sensors added by the recipe (bus.sensors) cross the bus like the built-in feeds: a batch's block
of their rows round-trips to typed messages, and any rows a peer may send decode or raise DecodeError."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus import feed
from bus.errors import DecodeError
from bus.sensors import SENSORS
from bus.sensors.camera3d import TrackedPoint
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


CAMERA3D = next(s for s in SENSORS if s.topic == "camera3d")


def _frame_batch(rows: np.ndarray, stamp_us: int = 100_000) -> bytes:
    blocks = {"camera3d": (np.full(len(rows), stamp_us, dtype=np.int64), 0, rows)}
    return feed.encode_batch(feed.SensorBatch(1, 0, 1_000_000, blocks))


def test_a_3d_camera_frame_is_several_points_with_one_stamp():
    rows = np.array([[7, 320.5, 200.0, 0.3, 1.0, 2.0, -0.1, 1.0], [9, 10.0, 470.0, 0.3, 1.0, 2.0, -0.1, 1.0]])
    samples = feed.decode_batch(_frame_batch(rows)).samples()
    assert [topic for topic, _ in samples] == ["camera3d", "camera3d"]
    first, second = (msg for _, msg in samples)
    assert first == TrackedPoint(1, 100_000, 0, 7, (320.5, 200.0), 0.3, (1.0, 2.0, -0.1), 1.0)
    assert (second.track_id, second.stamp_us) == (9, 100_000)


@pytest.mark.parametrize(
    "row, named",
    [
        ([1.5, 10, 10, 0, 0, 0, 0, 1], "track ids"),
        ([-1, 10, 10, 0, 0, 0, 0, 1], "track ids"),
        ([1, 641, 10, 0, 0, 0, 0, 1], "pixels"),
        ([1, 10, -1, 0, 0, 0, 0, 1], "pixels"),
        ([1, 10, 10, 4.0, 0, 0, 0, 1], "heading"),
        ([1, 10, 10, 0, 2000, 0, 0, 1], "displacement"),
        ([1, 10, 10, 0, 0, 0, 0, 11], "displacement"),
    ],
)
def test_an_impossible_tracked_point_is_refused_naming_what_is_wrong(row, named):
    with pytest.raises(DecodeError, match=f"camera3d.*{named}"):
        feed.decode_batch(_frame_batch(np.array([row], dtype=float)))


@given(
    st.lists(
        st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=8, max_size=8),
        min_size=1,
        max_size=10,
    )
)
def test_any_3d_camera_rows_decode_or_raise_decode_error(rows):
    try:
        batch = feed.decode_batch(_frame_batch(np.array(rows, dtype=float)))
    except DecodeError:
        return
    for _, msg in batch.samples():
        assert 0 <= msg.pixel[0] <= 640 and 0 <= msg.pixel[1] <= 480
        assert abs(msg.heading_rad) <= np.pi + 1e-9 and 0 <= msg.baseline_s <= 10
        assert np.isfinite(msg.baseline_m).all()
