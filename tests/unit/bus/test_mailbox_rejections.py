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


def _waiting_taker(box: Mailbox, **quiet) -> tuple[threading.Thread, list, list]:
    """A thread in ``box.get`` (up to 30 s) with ``quiet``, once it is asleep in the condition; and
    the list its item goes to, and the list counting the condition's notifications."""
    notified, taken = [], []
    notify = box.cond.notify

    def counting_notify(n: int = 1) -> None:
        notified.append(n)
        notify(n)

    box.cond.notify = counting_notify
    taker = threading.Thread(target=lambda: taken.append(box.get(30, **quiet)))
    taker.start()
    for _ in range(3000):  # asleep: it set the quiet lane under the lock, then released it in wait()
        with box.cond:
            if box._quiet is not None:
                break
        threading.Event().wait(0.01)
    return taker, taken, notified


def test_a_quiet_lane_wakes_its_taker_only_once_every_awaited_sender_has_sent():
    box = Mailbox()
    world, v2v = box.lane("world"), box.lane("v2v")
    awaited = {"v/2/v2v": 2, "v/2/v2v/1": 2, "v/3/v2v/1": 3}
    taker, taken, notified = _waiting_taker(box, quiet_lane=v2v, senders_by_key=awaited)
    v2v.put(Envelope("v/4/v2v/1", b"a"))  # a sender not awaited
    v2v.put(Envelope("v/2/v2v/1", b"b"))  # one of the two awaited
    v2v.put(Envelope("v/2/v2v", b"c"))  # the same sender again, on its broadcast key
    assert notified == [] and taker.is_alive()
    v2v.put(Envelope("v/3/v2v/1", b"d"))  # the last awaited sender: wakes it
    taker.join(30)
    assert notified == [1] and [t.key for t in taken] == ["v/4/v2v/1"]  # then it takes in lane order
    assert [box.get(0).key for _ in range(3)] == ["v/2/v2v/1", "v/2/v2v", "v/3/v2v/1"]
    world.put(Envelope("w", b""))  # no taker waits any more: every item notifies as before
    assert notified == [1, 1] and box.get(0).key == "w"


def test_other_lanes_still_wake_a_taker_that_waits_on_a_quiet_lane():
    box = Mailbox()
    world, v2v = box.lane("world"), box.lane("v2v")
    taker, taken, notified = _waiting_taker(box, quiet_lane=v2v, senders_by_key={})
    v2v.put(Envelope("v/2/v2v/1", b"a"))  # nobody awaited: the lane never wakes it
    assert notified == [] and taker.is_alive()
    world.put(Envelope("clock", b"t"))
    taker.join(30)
    assert notified == [1] and [t.key for t in taken] == ["clock"] and box.get(0).key == "v/2/v2v/1"


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
