"""What the ground station hears (groundstation.node): its mailbox's lanes, each bounded, and the
keys that feed them. The clock and the world's end of run, the fault requests and the id claims share
the control lane, served first; the truth, the vehicles' MAVLink streams and their status each have
a lane of their own, so a flood on one never starves another."""

from __future__ import annotations

from bus import feed
from bus.landmark_map import MAX_MAP_BYTES
from bus.mailbox import Lane, Mailbox
from bus.session import Bus
from groundstation.mavlink_in import MAX_STREAM_BYTES

MAX_CONTROL_BYTES = 8 << 10


def station_mailbox(bus: Bus) -> tuple[Mailbox, Lane]:
    """The ground station's mailbox, subscribed, and its control lane (which the liveliness watches
    feed too)."""
    keys, mailbox = bus.keys, Mailbox()
    control, truth = mailbox.lane("control", max_items=10_000), mailbox.lane("truth", max_items=10_000)
    mavlink, status = mailbox.lane("mavlink", max_items=200_000), mailbox.lane("status", max_items=20_000)
    for expr, lane, cap in (
        (keys.clock(), control, MAX_CONTROL_BYTES),
        (keys.end(), control, MAX_CONTROL_BYTES),
        (keys.truth(), truth, feed.MAX_TRUTH_BYTES),
        (keys.mavlink("*"), mavlink, MAX_STREAM_BYTES),
        (keys.status("*"), status, MAX_MAP_BYTES),
    ):
        bus.subscribe(expr, lane, cap)
    bus.queryable(keys.fault_request(), control)
    bus.queryable(keys.claim(), control)
    return mailbox, control
