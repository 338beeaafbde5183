"""The V2V side (vehicle.process.v2v): a ranging measurement is paired with the neighbour's broadcast of the
epoch at or before it, the neighbour carried to the measurement's instant along its heading (a
replayed camera sights robots between the broadcast epochs; the simulated world ranges on them)."""

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bus import messages as m
from bus.mavlink_codec import MAX_ACCUSED, MAX_V2V_BYTES, MavlinkEncoder, StateEstimate
from bus.rejections import Rejections
from vehicle.models.cooperative_fixes import SeenFix
from vehicle.process.v2v import V2V, fusion_turn_us, send_turn_us

PERIOD_US = 200_000


def _heard(yaw: float, tail: bytes = b"") -> V2V:
    """Vehicle 1's V2V, having heard vehicle 2 at epoch 0.2 s: at (3, 4) m, heading ``yaw``, 0.5 m/s
    (its ODOMETRY followed by ``tail``)."""
    v2v = V2V(1, latency_us=100_000, rejections=Rejections(logging.getLogger("test"), "test"), period_us=PERIOD_US)
    pose_cov = np.diag([0.04, 0.04, 1e-6, 1e-6, 1e-6, 0.01])
    est = StateEstimate(
        2,
        PERIOD_US,
        np.array([3.0, 4.0, 0.0]),
        yaw,
        np.array([0.5, 0.0, 0.0]),
        0.0,
        pose_cov,
        np.diag([0.0025, 1e-6, 1e-6, 1e-6, 1e-6, 1e-4]),
    )
    v2v.hear(2, PERIOD_US, MavlinkEncoder(vehicle_id=2).odometry(est) + tail)
    return v2v


def _ranging(stamp_us: int) -> m.RangeBearing:
    return m.RangeBearing(1, stamp_us, 0, 2, 5.0, 0.0, np.diag([0.01, 1e-4]))


def test_a_measurement_on_an_epoch_takes_the_broadcast_as_it_is():
    v2v = _heard(0.0)
    v2v.hold(_ranging(PERIOD_US))
    assert v2v.awaited(PERIOD_US + 100_000) == [(2, PERIOD_US)]
    (fix,) = v2v.mature(PERIOD_US + 100_000)
    assert np.allclose(fix.neighbour_xy_m, [3.0, 4.0]) and np.allclose(fix.neighbour_cov_m2, np.diag([0.04, 0.04]))


def test_a_measurement_between_epochs_carries_the_neighbour_to_its_instant():
    v2v = _heard(np.pi / 2)  # heading north: 0.5 m/s for 0.1 s is 5 cm north
    v2v.hold(_ranging(PERIOD_US + 100_000))
    assert v2v.awaited(PERIOD_US + 200_000) == [(2, PERIOD_US)]  # waits for the epoch's broadcast
    (fix,) = v2v.mature(PERIOD_US + 200_000)
    assert np.allclose(fix.neighbour_xy_m, [3.0, 4.05], atol=1e-6)
    grown = (0.0025 + 0.25 * 0.01) * 0.1**2  # (var v + v^2 var yaw) dt^2
    assert np.allclose(fix.neighbour_cov_m2, np.diag([0.04 + grown] * 2), atol=1e-9)
    assert v2v.missing == 0


def test_a_measurement_whose_epoch_was_not_heard_is_missing():
    v2v = _heard(0.0)
    v2v.hold(_ranging(2 * PERIOD_US + 50_000))  # pairs with epoch 0.4 s: never heard
    assert v2v.mature(10**7) == [] and v2v.missing == 1


def test_copies_of_one_epoch_are_decoded_when_used_and_the_last_good_one_counts():
    v2v = _heard(0.0)
    v2v.hear(2, PERIOD_US, b"\xfd not a frame")  # a broken copy after the good one
    v2v.hear(2, PERIOD_US, MavlinkEncoder(vehicle_id=2).no_estimate(PERIOD_US))  # and "no estimate"
    assert v2v.rejections.total == 0  # nothing decoded before a measurement needs the epoch
    v2v.hold(_ranging(PERIOD_US))
    (fix,) = v2v.mature(PERIOD_US + 100_000)
    assert np.allclose(fix.neighbour_xy_m, [3.0, 4.0])
    assert v2v.rejections.total == 1  # the broken copy, counted when it was looked at
    for _ in range(10):
        v2v.hear(2, 2 * PERIOD_US, b"flood")
    assert v2v.rejections.total == 1 + 10 - 4  # copies beyond four per epoch are refused as they come


def test_a_relayed_sighting_pairs_with_the_observers_whole_pose_carried_to_its_instant():
    """Vehicle 2 sighted vehicle 1 0.1 s after its broadcast: vehicle 1 gets vehicle 2's pose moved
    0.05 m along its heading (pi / 2: along y) and the pose covariance F P F^T + Q, where a heading
    error now moves the carried position across the heading: cov(x, yaw) = -v dt var(yaw)."""
    v2v = _heard(np.pi / 2)
    v2v.hold(m.SeenBy(1, PERIOD_US + 100_000, 0, 2, 5.0, 0.1, np.diag([0.01, 1e-4])))
    assert v2v.awaited(PERIOD_US + 200_000) == [(2, PERIOD_US)]
    (fix,) = v2v.mature(PERIOD_US + 200_000)
    assert isinstance(fix, SeenFix) and (fix.observer_id, fix.range_m, fix.bearing_rad) == (2, 5.0, 0.1)
    assert np.allclose(fix.observer_pose, [3.0, 4.05, np.pi / 2], atol=1e-9)
    v_dt, dt2 = 0.5 * 0.1, 0.1**2
    expected = np.array(
        [
            [0.04 + v_dt**2 * 0.01, 0.0, -v_dt * 0.01],
            [0.0, 0.04 + 0.0025 * dt2, 0.0],  # speed variance along the heading
            [-v_dt * 0.01, 0.0, 0.01 + 1e-4 * dt2],
        ]
    )  # yaw-rate variance on the heading
    assert np.allclose(fix.observer_cov, expected, atol=1e-12)


def _broadcast_with(tail: bytes) -> V2V:
    """Vehicle 1's V2V having heard vehicle 2's ODOMETRY of epoch 0.2 s followed by ``tail``, and a
    ranging of vehicle 2 that pairs with it."""
    v2v = _heard(0.0, tail)
    v2v.hold(_ranging(PERIOD_US))
    return v2v


def test_whom_a_neighbour_accuses_comes_with_its_fix():
    accuser = MavlinkEncoder(vehicle_id=2, link_id=2)
    v2v = _broadcast_with(accuser.accusation(PERIOD_US, 3) + accuser.accusation(PERIOD_US, 5))
    (fix,) = v2v.mature(PERIOD_US + 100_000)
    assert fix.neighbour_accuses == frozenset({3, 5}) and v2v.rejections.total == 0


@pytest.mark.parametrize(
    "tail, why",
    [
        (MavlinkEncoder(vehicle_id=4).accusation(PERIOD_US, 3), "in another's name"),
        (MavlinkEncoder(vehicle_id=2).accusation(2 * PERIOD_US, 3), "for another epoch"),
        (MavlinkEncoder(vehicle_id=2).accusation(PERIOD_US, 2), "of itself"),
        (MavlinkEncoder(vehicle_id=2).accusation(PERIOD_US, 256), "of no vehicle"),
        (MavlinkEncoder(vehicle_id=2).heartbeat(), "not an accusation"),
        (MavlinkEncoder(vehicle_id=2).accusation(PERIOD_US, 3) * (MAX_ACCUSED + 1), "too many"),
        (b"\x00", "a trailing byte"),
    ],
)
def test_a_broadcast_with_anything_but_its_senders_accusations_after_it_is_refused_whole(tail, why):
    v2v = _broadcast_with(tail)
    assert v2v.mature(PERIOD_US + 100_000) == [] and v2v.missing == 1, why
    assert v2v.rejections.total == 1


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=MAX_V2V_BYTES))
def test_any_bytes_after_an_odometry_frame_give_a_fix_or_a_counted_refusal(tail):
    v2v = _broadcast_with(tail)
    fixes = v2v.mature(PERIOD_US + 100_000)
    assert len(fixes) + v2v.rejections.total == 1
    assert all(0 < j <= 255 and j != 2 for fix in fixes for j in fix.neighbour_accuses)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 6), st.integers(-3, 300)), max_size=MAX_ACCUSED + 2), st.data())
def test_accusations_of_any_sender_and_value_mutated_anywhere_give_a_fix_or_a_counted_refusal(accusations, data):
    tail = bytearray(b"".join(MavlinkEncoder(vehicle_id=s).accusation(PERIOD_US, j) for s, j in accusations))
    if tail and data.draw(st.booleans()):
        tail[data.draw(st.integers(0, len(tail) - 1))] = data.draw(st.integers(0, 255))
    v2v = _broadcast_with(bytes(tail))
    fixes = v2v.mature(PERIOD_US + 100_000)
    assert len(fixes) + v2v.rejections.total == 1
    assert all(0 < j <= 255 and j != 2 for fix in fixes for j in fix.neighbour_accuses)


def test_realtime_vehicles_send_an_epochs_frames_in_turns_within_half_the_neighbours_wait():
    """A cycle apart, over the first half of the wait the neighbours give the frames (0, 20, 40 ms of
    100 ms at 50 Hz); one turn for all when a cycle is longer than half the wait."""
    turns = [send_turn_us(v, 20_000, 100_000) for v in range(1, 8)]
    assert turns == [0, 20_000, 40_000, 0, 20_000, 40_000, 0]
    assert {send_turn_us(v, 20_000, 30_000) for v in range(1, 8)} == {0}
    assert {send_turn_us(v, 20_000, 0) for v in range(1, 8)} == {0}


def test_realtime_vehicles_fuse_an_epoch_in_turns_over_half_the_v2v_period_within_the_horizon():
    """A cycle apart, over the first half of the V2V period (0-80 ms of 200 ms at 50 Hz), never beyond
    the room the fusion horizon leaves."""
    assert [fusion_turn_us(v, 20_000, 200_000, 900_000) for v in range(1, 7)] == [0, 20_000, 40_000, 60_000, 80_000, 0]
    assert {fusion_turn_us(v, 20_000, 200_000, 30_000) for v in range(1, 7)} == {0}
