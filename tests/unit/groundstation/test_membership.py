"""Joins and departures from the world's tick membership (groundstation.membership)."""

from groundstation.membership import MembershipLog


def test_joins_and_departures_follow_the_ticks_members():
    log = MembershipLog(resumed=False)
    assert log.change((1, 2, 3)) == ([1, 2, 3], [])
    assert log.change((1, 2, 3)) == ([], [])
    assert log.change((1, 3)) == ([], [2])  # killed: the next tick no longer waits for it
    assert log.change((3, 1, 2)) == ([2], [])  # restarted: waited for again
    assert log.change(()) == ([], [1, 2, 3])


def test_a_restarted_ground_station_takes_the_first_ticks_members_as_already_there():
    log = MembershipLog(resumed=True)
    assert log.change((1, 2)) == ([], [])
    assert log.change((1, 2, 4)) == ([4], [])
