"""The SLAM map on the wire: round trip, a clear DecodeError for each malformed case, nothing but
DecodeError for any bytes or any field value (hypothesis); the ground station keeps the last map of
each vehicle from its status key and writes it to the run directory, and refuses a map in another
vehicle's name."""

import json

import msgpack
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus import messages as m
from bus.config import build_config
from bus.errors import DecodeError
from bus.landmark_map import LandmarkMap, decode_map, encode_map
from bus.memory import MemoryHub
from bus.rejections import counts_to_dict
from bus.session import Envelope
from groundstation.node import GroundStation

XY = np.array([[1.0, 2.0], [-3.5, 40.25], [7.0, -8.0]])
COV = np.array([[[0.1, 0.02], [0.02, 0.2]], [[1.0, 0.0], [0.0, 1.0]], [[0.5, -0.1], [-0.1, 0.3]]])
PAYLOAD = encode_map(LandmarkMap(2, 1_500_000, XY, COV))
HEIGHT = np.array([-12.0, -9.5, 3.25])
COV3 = np.zeros((3, 3, 3))
COV3[:, :2, :2], COV3[:, 2, 2] = COV, [0.4, 2.0, 0.9]
COV3[:, 0, 2] = COV3[:, 2, 0] = [0.05, -0.3, 0.0]
PAYLOAD_3D = encode_map(LandmarkMap(2, 1_500_000, XY, COV, HEIGHT, COV3))


def test_round_trip():
    again = decode_map(PAYLOAD)
    assert (again.vehicle_id, again.stamp_us) == (2, 1_500_000)
    assert np.array_equal(again.xy_m, XY) and np.array_equal(again.covariance_m2, COV)


def test_a_3d_map_round_trips_with_its_heights_and_full_covariances():
    again = decode_map(PAYLOAD_3D)
    assert np.array_equal(again.xy_m, XY) and np.array_equal(again.covariance_m2, COV)
    assert np.array_equal(again.height_m, HEIGHT) and np.array_equal(again.covariance3_m2, COV3)
    assert decode_map(PAYLOAD).height_m is None and decode_map(PAYLOAD).covariance3_m2 is None


def _body(payload: bytes = PAYLOAD) -> dict:
    return msgpack.unpackb(payload, raw=False)


@pytest.mark.parametrize(
    "mutate, reason",
    [
        (lambda b: b.update(vehicle_id=0), "vehicle_id"),
        (lambda b: b.update(type="VehicleStatus"), "type tag"),
        (lambda b: b.update(extra=1), "fields"),
        (lambda b: b.update(xy=b["xy"][:-8]), "rows of 2"),
        (lambda b: b.update(cov=b["cov"][:-24]), "positions but 2 covariances"),
        (lambda b: b.update(xy=np.array([[np.nan, 0.0]] * 3).tobytes()), "finite"),
        (lambda b: b.update(cov=np.array([[1.0, 2.0, 1.0]] * 3).tobytes()), "positive definite"),
        (lambda b: b.update(cov=np.array([[-1.0, 0.0, 1.0]] * 3).tobytes()), "positive definite"),
    ],
)
def test_malformed_maps_are_rejected_with_a_clear_error(mutate, reason):
    body = _body()
    mutate(body)
    with pytest.raises(DecodeError, match=reason):
        decode_map(msgpack.packb(body, use_bin_type=True))


@pytest.mark.parametrize(
    "mutate, reason",
    [
        (lambda b: b.pop("cov_z"), "both or neither"),
        (lambda b: b.pop("z"), "both or neither"),
        (lambda b: b.update(z=b["z"][:-8]), "3 positions but 2 heights"),
        (lambda b: b.update(cov_z=b["cov_z"][:-8]), "rows of 3"),
        (lambda b: b.update(z=np.array([np.inf, 0.0, 0.0]).tobytes()), "finite"),
        (lambda b: b.update(cov_z=np.array([[0.0, 0.0, -1.0]] * 3).tobytes()), "3-D covariances must be positive"),
        (lambda b: b.update(cov_z=np.array([[5.0, 0.0, 1.0]] * 3).tobytes()), "3-D covariances must be positive"),
    ],
)
def test_malformed_3d_maps_are_rejected_with_a_clear_error(mutate, reason):
    body = _body(PAYLOAD_3D)
    mutate(body)
    with pytest.raises(DecodeError, match=reason):
        decode_map(msgpack.packb(body, use_bin_type=True))


@given(st.binary(max_size=300))
def test_any_bytes_decode_or_raise_decode_error(payload):
    try:
        decode_map(payload)
    except DecodeError:
        pass


@given(
    st.sampled_from(["type", "v", "vehicle_id", "stamp_us", "xy", "cov", "z", "cov_z"]),
    st.booleans(),
    st.none()
    | st.booleans()
    | st.integers(-(2**63), 2**64 - 1)
    | st.floats()
    | st.text(max_size=8)
    | st.binary(max_size=64),
)
def test_any_value_in_any_field_decodes_or_raises_decode_error(field, three_d, value):
    body = _body(PAYLOAD_3D if three_d else PAYLOAD)
    body[field] = value
    try:
        decode_map(msgpack.packb(body, use_bin_type=True))
    except DecodeError:
        pass


def test_the_ground_station_keeps_the_last_map_and_refuses_one_in_another_name(tmp_path):
    config = build_config({"world": {"vehicles": 3}, "clock": {"duration_s": 10}})
    gs = GroundStation(MemoryHub().connect("groundstation"), config, tmp_path / "run", master_key=bytes(32))
    keys = gs.bus.keys
    older = encode_map(LandmarkMap(2, 500_000, XY[:1], COV[:1]))
    for payload in (older, PAYLOAD, m.encode(m.VehicleStatus(2, 1_500_000, 75, 0, 0.0, 0.0, 0, 0, 0, 0))):
        gs.handle(Envelope(keys.status(2), payload))
    gs.handle(Envelope(keys.status(1), PAYLOAD))  # vehicle 2's map on vehicle 1's key
    gs.handle(Envelope(keys.status(1), b"\x81\xa1x\x01"))  # neither a status nor a map
    assert counts_to_dict(gs.rejections.as_counts()) == {"impersonation": 1, "malformed": 1}
    assert set(gs.reports.maps) == {2} and 2 in gs.reports.statuses
    gs.finish("complete")
    written = json.loads((tmp_path / "run" / "map_v2.json").read_text())
    assert written["landmarks"] == 3 and written["xy_m"][1] == [-3.5, 40.25] and written["t_s"] == 1.5
