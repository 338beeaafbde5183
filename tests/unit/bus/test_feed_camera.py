"""Camera frames in the sensor batch: round trip, a clear DecodeError for every malformed block, and
nothing but DecodeError for any value in any camera field (hypothesis)."""

import msgpack
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus import feed
from bus.config import build_config
from bus.errors import DecodeError
from sim.world import World


def _batch() -> feed.SensorBatch:
    world = World(
        build_config({"world": {"vehicles": 2, "seed": 4, "terrain_size_px": 512}, "sensors": {"camera_rate_hz": 10}})
    )
    out = world.advance(200_000)
    return feed.SensorBatch(1, 2, 200_000, out.blocks(1), out.camera(1))


BATCH = _batch()
PAYLOAD = feed.encode_batch(BATCH)


def test_frames_round_trip_with_their_stamps_scale_and_pixels():
    again = feed.decode_batch(PAYLOAD)
    frames = [msg for topic, msg in again.samples() if topic == "camera"]
    assert [f.stamp_us for f in frames] == [0, 100_000, 200_000] and [f.seq for f in frames] == [0, 1, 2]
    for k, frame in enumerate(frames):
        assert frame.pixels.shape == (80, 80) and frame.pixels.dtype == np.uint8 and frame.metres_per_pixel == 0.1
        assert np.array_equal(frame.pixels, BATCH.camera.pixels[k])
    assert frames[0].pixels.std() > 10  # the ground has texture


def _body() -> dict:
    return msgpack.unpackb(PAYLOAD, raw=False)


@pytest.mark.parametrize(
    "mutate, reason",
    [
        (lambda c: c.update(pixels=c["pixels"][:-1]), "pixel bytes"),
        (lambda c: c.update(size=81), "pixel bytes"),
        (lambda c: c.update(size=4), "size"),
        (lambda c: c.update(scale=c["scale"][:-8]), "scales"),
        (lambda c: c.update(scale=np.array([0.1, -1.0, 0.1]).tobytes()), "ground scale"),
        (lambda c: c.update(scale=np.array([0.1, np.nan, 0.1]).tobytes()), "ground scale"),
        (lambda c: c.update(stamp=np.array([0, 0, 100_000], "<i8").tobytes()), "increasing"),
        (lambda c: c.update(stamp=np.array([0, 100_000, 900_000], "<i8").tobytes()), "inside the tick"),
        (lambda c: c.update(pixels="text"), "pixel bytes"),
        (lambda c: c.pop("scale"), "block"),
    ],
)
def test_malformed_camera_blocks_are_rejected_with_a_clear_error(mutate, reason):
    body = _body()
    mutate(body["camera"])
    with pytest.raises(DecodeError, match=reason):
        feed.decode_batch(msgpack.packb(body, use_bin_type=True))


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


@given(st.sampled_from(["camera", "stamp", "seq0", "size", "scale", "pixels"]), json_like)
def test_any_value_in_any_camera_field_decodes_or_raises_decode_error(field, value):
    body = _body()
    if field == "camera":
        body["camera"] = value
    else:
        body["camera"][field] = value
    try:
        batch = feed.decode_batch(msgpack.packb(body, use_bin_type=True))
    except DecodeError:
        return
    for topic, msg in batch.samples():  # whatever passes has the promised shape
        if topic == "camera":
            assert msg.pixels.ndim == 2 and msg.pixels.shape[0] == msg.pixels.shape[1] and msg.metres_per_pixel > 0
