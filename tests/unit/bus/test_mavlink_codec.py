"""MAVLink 2 ODOMETRY/HEARTBEAT codec and the signing guard."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mavlink2

from bus.errors import DecodeError
from bus.mavlink_codec import (
    ACCUSATION_FRAME_BYTES,
    COMPONENT_ID,
    Accusation,
    EstimatorStatus,
    Heartbeat,
    MavlinkDecoder,
    MavlinkEncoder,
    MavlinkRejected,
    NoEstimate,
    StateEstimate,
    StatusText,
    signing_now,
)

KEY = bytes(range(32))


def _estimate(t_us: int = 1_000_000, vehicle_id: int = 3) -> StateEstimate:
    rng = np.random.default_rng(1)
    a = rng.normal(size=(6, 6))
    return StateEstimate(
        vehicle_id,
        t_us,
        np.array([10.0, -4.0, -30.0]),
        2.5,
        np.array([4.0, 0.0, 0.0]),
        0.2,
        a @ a.T + np.eye(6),
        np.diag([0.1, 0.2, 0.3, 0.4, 0.5, 0.6]),
        reset_counter=4,
    )


def test_odometry_round_trip_keeps_pose_covariance_and_metadata():
    est = _estimate()
    out = MavlinkDecoder().decode(MavlinkEncoder(vehicle_id=3).odometry(est))
    assert out.vehicle_id == 3 and out.time_usec == est.time_usec and out.reset_counter == 4
    assert out.yaw_rad == pytest.approx(2.5, abs=1e-6)
    np.testing.assert_allclose(out.position_m, est.position_m, rtol=1e-6)
    np.testing.assert_allclose(out.pose_covariance, est.pose_covariance, rtol=1e-6)
    np.testing.assert_allclose(out.velocity_covariance, est.velocity_covariance, rtol=1e-6)


def test_an_odometry_of_unknown_covariance_says_no_estimate_and_nothing_else():
    """MAVLink: "If unknown, assign NaN value to first element in the array"; any other non-finite
    field is still degenerate."""
    frame = MavlinkEncoder(vehicle_id=4, signing_key=KEY).no_estimate(1_200_000)
    assert MavlinkDecoder(signing_key=KEY).decode(frame) == NoEstimate(4, 1_200_000)
    est = _estimate()
    cov = est.pose_covariance.copy()
    cov[1, 1] = np.nan
    with pytest.raises(MavlinkRejected):
        MavlinkDecoder().decode(
            MavlinkEncoder(vehicle_id=3).odometry(
                StateEstimate(
                    3, est.time_usec, est.position_m, 0.0, est.velocity_mps, 0.0, cov, est.velocity_covariance
                )
            )
        )


def test_frames_are_mavlink2_with_vehicle_sysid_and_compid_191():
    frame = MavlinkEncoder(vehicle_id=7).heartbeat()
    msg = mavlink2.MAVLink(None).decode(bytearray(frame))
    assert frame[0] == mavlink2.PROTOCOL_MARKER_V2
    assert (msg.get_srcSystem(), msg.get_srcComponent()) == (7, COMPONENT_ID)
    assert MavlinkDecoder().decode(frame) == Heartbeat(7, mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_STATE_ACTIVE)


def test_signed_stream_is_accepted_and_unsigned_rejected():
    decoder = MavlinkDecoder(signing_key=KEY)
    assert decoder.decode(MavlinkEncoder(vehicle_id=3, signing_key=KEY).odometry(_estimate())).vehicle_id == 3
    with pytest.raises(MavlinkRejected, match="unsigned"):
        decoder.decode(MavlinkEncoder(vehicle_id=3).odometry(_estimate()))
    assert decoder.rejected["unsigned"] == 1


def test_wrong_key_and_replay_are_rejected():
    decoder = MavlinkDecoder(signing_key=KEY)
    with pytest.raises(MavlinkRejected, match="bad_signature"):
        decoder.decode(MavlinkEncoder(vehicle_id=3, signing_key=bytes(32)).odometry(_estimate()))
    frame = MavlinkEncoder(vehicle_id=3, signing_key=KEY).odometry(_estimate())
    decoder.decode(frame)
    with pytest.raises(MavlinkRejected, match="replay"):
        decoder.decode(frame)


def _forge_far_future(frame: bytes) -> bytes:
    """A copy of ``frame`` with its signing timestamp pushed far ahead and a garbage signature."""
    stamp = (signing_now() + 10**12).to_bytes(6, "little")
    return frame[:-12] + stamp + b"\xde\xad\xbe\xef\x00\x01"


def test_forged_far_future_frame_does_not_block_the_genuine_stream():
    encoder = MavlinkEncoder(vehicle_id=3, signing_key=KEY)
    decoder = MavlinkDecoder(signing_key=KEY)
    decoder.decode(encoder.odometry(_estimate(1_000_000)))
    with pytest.raises(MavlinkRejected, match="bad_signature"):
        decoder.decode(_forge_far_future(encoder.odometry(_estimate(1_020_000))))
    assert decoder.decode(encoder.odometry(_estimate(1_040_000))).time_usec == 1_040_000


def test_pymavlink_alone_is_blocked_by_the_same_forgery():
    """Documents why the guard exists: pymavlink 2.4.50 stores the timestamp before checking."""
    encoder = MavlinkEncoder(vehicle_id=3, signing_key=KEY)
    parser = mavlink2.MAVLink(None)
    parser.signing.secret_key = KEY
    parser.decode(bytearray(encoder.odometry(_estimate())))
    with pytest.raises(mavlink2.MAVError):
        parser.decode(bytearray(_forge_far_future(encoder.odometry(_estimate()))))
    with pytest.raises(mavlink2.MAVError):
        parser.decode(bytearray(encoder.odometry(_estimate())))


@given(st.binary(max_size=300))
def test_garbage_frames_raise_decode_error_only(frame):
    try:
        MavlinkDecoder(signing_key=KEY).decode(frame)
    except DecodeError:
        pass


@given(st.data())
def test_mutated_frames_raise_decode_error_or_decode(data):
    frame = bytearray(MavlinkEncoder(vehicle_id=3).odometry(_estimate()))
    for _ in range(data.draw(st.integers(1, 3))):
        frame[data.draw(st.integers(0, len(frame) - 1))] = data.draw(st.integers(0, 255))
    try:
        MavlinkDecoder().decode(bytes(frame))
    except DecodeError:
        pass


def test_estimator_status_and_statustext_round_trip_signed():
    key = bytes(range(32))
    encoder, decoder = MavlinkEncoder(vehicle_id=4, signing_key=key), MavlinkDecoder(signing_key=key)
    status = decoder.decode(
        encoder.estimator_status(
            EstimatorStatus(4, 12_000_000, mavlink2.ESTIMATOR_GPS_GLITCH | mavlink2.ESTIMATOR_ATTITUDE, 1.75, 0.5)
        )
    )
    assert status.vehicle_id == 4 and status.time_usec == 12_000_000 and status.gps_glitch
    assert status.pos_horiz_ratio == pytest.approx(1.75)
    text = decoder.decode(encoder.statustext(4, "GNSS unhealthy: spoofing suspected"))
    assert text == StatusText(4, 4, "GNSS unhealthy: spoofing suspected")


def test_a_far_future_signing_timestamp_is_refused_even_with_the_right_key():
    encoder = MavlinkEncoder(vehicle_id=3, signing_key=KEY)
    decoder = MavlinkDecoder(signing_key=KEY)
    encoder._mav.signing.timestamp = signing_now() + 10 * 86_400 * 100_000  # a key holder ten days ahead
    with pytest.raises(MavlinkRejected, match="future_timestamp"):
        decoder.decode(encoder.odometry(_estimate()))
    genuine = MavlinkEncoder(vehicle_id=3, signing_key=KEY)
    assert decoder.decode(genuine.odometry(_estimate())).vehicle_id == 3  # the stream was not frozen


@pytest.mark.parametrize(
    "cov",
    [
        np.zeros((6, 6)),  # all zeros
        np.diag([1.0, 1.0, 1e-6, 1e-6, 1e-6, 0.0]),  # singular in yaw
        np.diag([1.0, 4.0, 1e-6, 1e-6, 1e-6, 1.0])
        + np.pad([[0.0, 3.0], [3.0, 0.0]], ((0, 4), (0, 4))),  # indefinite: xy det < 0
        np.diag([1e12, 1.0, 1e-6, 1e-6, 1e-6, 1.0]),  # huge
    ],
    ids=["zero", "singular", "indefinite", "huge"],
)
def test_degenerate_covariances_are_rejected(cov):
    est = StateEstimate(3, 1_000_000, np.array([1.0, 2.0, -30.0]), 0.1, np.zeros(3), 0.0, cov, np.eye(6))
    with pytest.raises(MavlinkRejected, match="degenerate"):
        MavlinkDecoder().decode(MavlinkEncoder(vehicle_id=3).odometry(est))


def test_each_sender_is_checked_against_its_own_key_and_unknown_senders_are_refused():
    keys = {1: bytes([1] * 32), 2: bytes([2] * 32)}
    decoder = MavlinkDecoder(key_for=keys.get)
    assert (
        decoder.decode(MavlinkEncoder(vehicle_id=2, signing_key=keys[2]).odometry(_estimate(vehicle_id=2))).vehicle_id
        == 2
    )
    with pytest.raises(MavlinkRejected, match="bad_signature"):  # vehicle 1's key speaking as vehicle 2
        decoder.decode(MavlinkEncoder(vehicle_id=2, signing_key=keys[1]).odometry(_estimate(vehicle_id=2)))
    with pytest.raises(MavlinkRejected, match="unknown_sysid"):
        decoder.decode(MavlinkEncoder(vehicle_id=9, signing_key=keys[1]).odometry(_estimate(vehicle_id=9)))


def test_concatenated_frames_split_by_their_lengths():
    from bus.mavlink_codec import split_frames

    frames = [
        MavlinkEncoder(vehicle_id=3, signing_key=KEY).odometry(_estimate()),
        MavlinkEncoder(vehicle_id=3).heartbeat(),
    ]
    assert split_frames(b"".join(frames)) == (frames, 0)
    assert split_frames(b"".join(frames) + b"\xfd\x05") == (frames, 2)
    assert split_frames(b"junk" + frames[0]) == ([], len(frames[0]) + 4)


@given(st.binary(max_size=1200))
def test_splitting_any_bytes_is_total(buffer):
    from bus.mavlink_codec import split_frames

    frames, rest = split_frames(buffer)
    assert sum(map(len, frames)) + rest == len(buffer)


@given(st.lists(st.floats(-10.0, 10.0), min_size=9, max_size=9), st.floats(1e-12, 1e3))
def test_the_written_out_covariance_check_agrees_with_lapack(entries, scale):
    from bus.mavlink_codec import MAX_VARIANCE, _usable_covariance

    A = np.array(entries).reshape(3, 3)
    for C in (A @ A.T * scale, (A + A.T) * scale):  # positive semi-definite; any symmetric
        try:
            L = np.linalg.cholesky(C)
            d = np.diag(L)
            expected = bool(np.min(d) > 1e-9 * np.max(d)) and np.max(np.diag(C)) <= MAX_VARIANCE
        except np.linalg.LinAlgError:
            expected = False
        d = np.sort(np.linalg.eigvalsh(C))
        if abs(d[0]) > 1e-9 * max(abs(d[-1]), 1e-300):  # away from the boundary the two must agree
            assert _usable_covariance(C) == expected


def test_an_accusation_round_trips_signed_and_other_named_values_are_not_one():
    key = bytes(range(32))
    encoder, decoder = MavlinkEncoder(vehicle_id=4, signing_key=key, link_id=2), MavlinkDecoder(signing_key=key)
    frame = encoder.accusation(5_000_200_000, 3)
    assert len(frame) <= ACCUSATION_FRAME_BYTES
    assert decoder.decode(frame) == Accusation(4, 5_000_200, 3)
    mav = mavlink2.MAVLink(None, srcSystem=4, srcComponent=191)
    assert MavlinkDecoder().decode(bytes(mav.named_value_int_encode(0, b"rpm", 3).pack(mav))) is None


def test_system_time_says_the_senders_time_in_ms_modulo_2_32():
    from bus.mavlink_codec import SystemTime

    decoder = MavlinkDecoder()
    for time_us, ms in ((760_000, 760), (2**32 * 1000 + 5_000, 5)):
        assert decoder.decode(MavlinkEncoder(vehicle_id=4).system_time(time_us)) == SystemTime(4, ms)
