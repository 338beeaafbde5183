"""Bounded mailboxes (a full lane refuses and counts; lanes are served in order) and rejection
accounting (counted by reason, logged once per reason and place)."""

import logging
import threading

import pytest

from bus.mailbox import Mailbox
from bus.rejections import REASONS, Rejections, counts_to_dict
from bus.session import Envelope


def test_a_full_lane_refuses_and_counts_without_touching_the_others():
    box = Mailbox()
    world, v2v = box.lane("world", max_items=3), box.lane("v2v", max_items=2, max_bytes=10)
    assert all(v2v.put(Envelope("k", b"12345")) for _ in range(2))
    assert not v2v.put(Envelope("k", b"1"))  # item bound
    assert world.put(Envelope("w", b"x" * 100))
    assert box.dropped() == 1
    assert box.get(0).key == "w"  # lanes in the order they were made
    assert box.get(0).key == "k" and box.get(0).key == "k" and box.get(0.01) is None


def test_byte_bound_refuses_big_items():
    box = Mailbox()
    lane = box.lane("x", max_items=100, max_bytes=10)
    assert lane.put(Envelope("k", b"1234567890")) and not lane.put(Envelope("k", b"1"))


def test_get_nowait_from_takes_from_that_lane_only_and_frees_its_bytes():
    box = Mailbox()
    first, second = box.lane("first"), box.lane("second")
    second.put(Envelope("k/b", b"12345"))
    assert box.get_nowait_from(first) is None
    first.put(Envelope("k/a", b"xyz"))
    assert box.get_nowait_from(second).key == "k/b" and second.bytes == 0
    assert box.get_nowait_from(first).key == "k/a" and first.bytes == 0 and box.empty()


def test_get_wakes_up_when_another_thread_puts():
    box = Mailbox()
    lane = box.lane("x")
    threading.Timer(0.05, lambda: lane.put(Envelope("k", b"late"))).start()
    assert box.get(2.0).payload == b"late"


def test_rejections_are_counted_by_reason_and_logged_once_per_place(caplog):
    rejections = Rejections(logging.getLogger("test"), "tester")
    with caplog.at_level(logging.WARNING):
        for _ in range(5):
            rejections.reject("malformed", "swarm/v/1/feed", "bad")
        rejections.reject("malformed", "swarm/v/2/feed", "bad")
        rejections.reject("oversized", "swarm/v/1/feed", "big", count=3)
    assert counts_to_dict(rejections.as_counts()) == {"malformed": 6, "oversized": 3}
    assert len(caplog.records) == 3 and rejections.total == 9
    assert len(rejections.as_counts()) == len(REASONS)
    with pytest.raises(ValueError):
        rejections.reject("made-up", "x")
