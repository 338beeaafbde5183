"""ODOMETRY frames read straight from the wire (bus.odometry_wire) decode to exactly what pymavlink's
decoder gives: the same estimate, or the same refusal, for any fields, signed or not, and for any
frame corrupted on the way."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from bus import mavlink_codec, mavlink_decoder, odometry_wire
from bus.errors import DecodeError
from bus.estimate import Altitude, PoseEstimate
from bus.mavlink_codec import MavlinkDecoder, MavlinkEncoder, MavlinkRejected, StateEstimate, odometry_of, pose_of

KEY = bytes(range(32))
nine = lambda elements: st.lists(elements, min_size=9, max_size=9)  # noqa: E731
VALID = [0.1, 0.0, 0.0, 0.0, 0.0, 0.01, 0.1, 0.0, 0.0, 0.0, 0.01, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.2]
floats = st.one_of(
    st.floats(-1e3, 1e3),
    st.sampled_from([0.0, -0.0, 1e-12, 1e9, math.inf, -math.inf, math.nan]),
)

FRAME_FIELDS = dict(  # any ODOMETRY frame's fields (_frame)
    sysid=st.integers(1, 250),
    signed=st.booleans(),
    time_usec=st.integers(0, 2**63 - 1),
    values=st.one_of(nine(st.floats(-100.0, 100.0)), nine(floats)),
    cov=st.one_of(st.just(VALID), st.lists(st.one_of(st.floats(1e-6, 10.0), floats), min_size=21, max_size=21)),
    trailing=st.integers(0, 255),
)


def _frame(sysid: int, signed: bool, time_usec: int, values: list[float], cov: list[float], trailing: int) -> bytes:
    """A raw ODOMETRY frame of these fields (pymavlink's encoder: it trims the payload's trailing zeros)."""
    encoder = MavlinkEncoder(vehicle_id=sysid, signing_key=KEY if signed else None)
    x, y, z, qw, qz, vx, vy, vz, yawspeed = values
    msg = encoder._mav.odometry_encode(
        time_usec, 1, 12, x, y, z, [qw, 0.0, 0.0, qz], vx, vy, vz, 0.0, 0.0, yawspeed, cov, cov[::-1], trailing, 2, 0
    )
    return encoder._pack(msg)


def _outcome(read, frame: bytes):
    """What ``read`` (a decoder's decode or decode_pose) makes of ``frame``, comparable by value."""
    try:
        result = read(frame)
    except MavlinkRejected as exc:
        return ("rejected", exc.reason)
    except DecodeError:
        return ("malformed",)
    if isinstance(result, (StateEstimate, PoseEstimate)):
        return tuple(np.asarray(v).tobytes() if isinstance(v, np.ndarray) else v for v in vars(result).values())
    return result


def _both(frame: bytes, signed: bool) -> tuple:
    """What the decoder gives with the wire reader, then with pymavlink alone (fresh decoders: the
    signing timestamps of a stream are remembered)."""
    make = lambda: MavlinkDecoder(key_for=lambda sysid: KEY) if signed else MavlinkDecoder()  # noqa: E731
    fast = _outcome(make().decode, frame)
    with pytest.MonkeyPatch.context() as patched:
        patched.setattr(mavlink_decoder, "odometry_fields", lambda frame: None)
        slow = _outcome(make().decode, frame)
    return fast, slow


@settings(max_examples=300, deadline=None)
@given(**FRAME_FIELDS)
def test_any_odometry_frame_decodes_as_pymavlink_decodes_it(sysid, signed, time_usec, values, cov, trailing):
    fast, slow = _both(_frame(sysid, signed, time_usec, values, cov, trailing), signed)
    assert fast == slow


@settings(max_examples=300, deadline=None)
@given(position=st.integers(0, 120), byte=st.integers(0, 255), cut=st.integers(0, 20), signed=st.booleans())
def test_a_corrupted_odometry_frame_is_refused_as_pymavlink_refuses_it(position, byte, cut, signed):
    frame = bytearray(_frame(3, signed, 1_000_000, [1.0, 2.0, -30.0, 1.0, 0.1, 1.0, 0.0, 0.0, 0.1], VALID, 0))
    frame[position % len(frame)] = byte
    frame = bytes(frame[: len(frame) - cut])
    fast, slow = _both(frame, signed)
    assert fast == slow


def test_only_a_well_formed_odometry_frame_is_read_from_the_wire():
    heartbeat = MavlinkEncoder(vehicle_id=2).heartbeat()
    odometry = _frame(2, False, 5, [0.0] * 3 + [1.0] + [0.0] * 5, [1.0] * 21, 0)
    assert odometry_wire.odometry_fields(heartbeat) is None
    assert odometry_wire.odometry_fields(odometry[:-1]) is None  # its length no longer checks out
    fields = odometry_wire.odometry_fields(odometry)
    valid = _frame(2, True, 7, [1.0, 2.0, -30.0, 1.0, 0.1, 1.0, 0.0, 0.0, 0.1], VALID, 0)
    estimate = MavlinkDecoder(key_for=lambda sysid: KEY).decode(valid)
    assert isinstance(estimate, StateEstimate) and estimate.time_usec == 7 and estimate.position_m[2] == -30.0
    assert fields[odometry_wire.TIME_USEC] == 5 and fields[odometry_wire.Q] == (1.0, 0.0, 0.0, 0.0)
    assert fields[odometry_wire.ESTIMATOR_TYPE] == 2 and len(fields) == 61


def _pymavlink_odometry(encoder: MavlinkEncoder, est: StateEstimate) -> bytes:
    """The frame pymavlink's own encoder packs for ``est`` (the reference)."""
    half = 0.5 * est.yaw_rad
    msg = encoder._mav.odometry_encode(
        est.time_usec,
        mavlink2.MAV_FRAME_LOCAL_NED,
        mavlink2.MAV_FRAME_BODY_FRD,
        *map(float, est.position_m),
        [float(np.cos(half)), 0.0, 0.0, float(np.sin(half))],
        *map(float, est.velocity_mps),
        0.0,
        0.0,
        float(est.yaw_rate_radps),
        est.pose_covariance[np.triu_indices(6)].tolist(),
        est.velocity_covariance[np.triu_indices(6)].tolist(),
        est.reset_counter % 256,
        est.estimator_type,
        100,
    )
    return encoder._pack(msg)


@settings(max_examples=200, deadline=None)
@given(
    sysid=st.integers(1, 250),
    signed=st.booleans(),
    link_id=st.integers(0, 255),
    seq=st.integers(0, 255),
    time_usec=st.integers(0, 2**63 - 1),
    values=st.one_of(nine(st.floats(-100.0, 100.0)), nine(floats)),
    cov=st.lists(st.one_of(st.just(0.0), floats), min_size=36, max_size=36),
    reset_counter=st.integers(0, 1000),
)
def test_an_odometry_frame_is_packed_as_pymavlink_packs_it(
    sysid, signed, link_id, seq, time_usec, values, cov, reset_counter
):
    """Byte for byte, two frames in a row (the sequence number and the signing timestamp move on),
    and the "no estimate" frame too."""
    covariance = np.array(cov).reshape(6, 6)
    est = StateEstimate(
        sysid,
        time_usec,
        np.array(values[:3]),
        values[3],
        np.array(values[4:7]),
        values[7],
        covariance,
        covariance.T,
        reset_counter,
        2,
    )
    with pytest.MonkeyPatch.context() as monkeypatch, np.errstate(invalid="ignore"):  # a yaw of inf or NaN
        monkeypatch.setattr(mavlink_codec, "signing_now", lambda: 123_456_789)
        fast, slow = (
            MavlinkEncoder(vehicle_id=sysid, signing_key=KEY if signed else None, link_id=link_id) for _ in range(2)
        )
        fast._mav.seq = slow._mav.seq = seq
        for _ in range(2):
            assert fast.odometry(est) == _pymavlink_odometry(slow, est)
        unknown = [math.nan] + [0.0] * 20
        pose, rates = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0], [0.0] * 6  # x, y, z, q; velocities and rates
        fields = [time_usec, 1, 12, *pose[:3], pose[3:], *rates, unknown, unknown, reset_counter % 256]
        reference = slow._mav.odometry_encode(*fields, mavlink2.MAV_ESTIMATOR_TYPE_GPS_INS, 0)
        assert fast.no_estimate(time_usec, reset_counter) == slow._pack(reference)


def _planar(decoded):
    """``decode``'s result with an estimate made planar (``pose_of``)."""
    return pose_of(decoded) if isinstance(decoded, StateEstimate) else decoded


@settings(max_examples=300, deadline=None)
@given(
    **FRAME_FIELDS,
    corrupt=st.one_of(st.none(), st.tuples(st.integers(0, 120), st.integers(0, 255))),
)
def test_a_broadcast_reads_as_the_planar_estimate_of_its_decoded_odometry(
    sysid, signed, time_usec, values, cov, trailing, corrupt
):
    """A neighbour's broadcast read straight to its planar estimate (``decode_pose``) gives exactly
    ``pose_of`` of what ``decode`` gives, or the same refusal, counted the same."""
    frame = bytearray(_frame(sysid, signed, time_usec, values, cov, trailing))
    if corrupt is not None:
        frame[corrupt[0] % len(frame)] = corrupt[1]
    make = lambda: MavlinkDecoder(key_for=lambda sysid: KEY) if signed else MavlinkDecoder()  # noqa: E731
    planar, full = make(), make()
    expected = _outcome(lambda raw: _planar(full.decode(raw)), bytes(frame))
    assert _outcome(planar.decode_pose, bytes(frame)) == expected
    assert planar.rejected == full.rejected


@settings(max_examples=300, deadline=None)
@given(
    sysid=st.integers(1, 250),
    signed=st.booleans(),
    time_usec=st.integers(0, 2**63 - 1),
    values=st.one_of(nine(st.floats(-100.0, 100.0)), nine(floats)),
    cov=st.lists(st.one_of(st.just(0.0), floats), min_size=9, max_size=9),
    altitude=st.one_of(st.floats(0.0, 100.0), floats),
    height=st.one_of(st.none(), st.tuples(floats, floats, floats, floats)),
    reset_counter=st.integers(0, 1000),
)
def test_a_planar_estimate_is_packed_as_its_odometry_is(
    sysid, signed, time_usec, values, cov, altitude, height, reset_counter
):
    """``pose_odometry`` packs byte for byte the frame ``odometry(odometry_of(...))`` packs, two in a row,
    with or without an estimated height."""
    own = None if height is None else Altitude(height[0], height[1], height[2:])
    est = PoseEstimate(sysid, time_usec, np.array(values[:3]), np.array(cov).reshape(3, 3), *values[3:7], own)
    with pytest.MonkeyPatch.context() as monkeypatch, np.errstate(invalid="ignore"):  # a yaw of inf or NaN
        monkeypatch.setattr(mavlink_codec, "signing_now", lambda: 123_456_789)
        fast, slow = (MavlinkEncoder(vehicle_id=sysid, signing_key=KEY if signed else None) for _ in range(2))
        for _ in range(2):
            expected = slow.odometry(odometry_of(est, altitude_m=altitude, reset_counter=reset_counter))
            assert fast.pose_odometry(est, altitude_m=altitude, reset_counter=reset_counter) == expected
