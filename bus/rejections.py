"""Rejected input, counted by reason and logged once per (reason, where): never fatal.

Every process keeps one :class:`Rejections`. Counts travel to the ground station as a tuple in the
order of ``REASONS`` (vehicle status, run end) and end up in ``summary.json``.
"""

from __future__ import annotations

import logging
import threading
from collections import Counter
from collections.abc import Callable

REASONS = (
    "bad_key",  # a key that names nothing of ours (non-decimal id, unknown topic, ...)
    "unknown_vehicle",  # a well-formed vehicle id that is not in the swarm
    "oversized",  # payload over the size cap of its topic (checked before decoding)
    "malformed",  # not decodable: garbage, truncated, wrong types, shapes or ranges
    "unsigned",  # MAVLink: unsigned frame where signing is required
    "bad_signature",  # MAVLink: signature does not match the sender's key
    "replay",  # MAVLink: signing timestamp not after the stream's last one
    "stale_stream",  # MAVLink: a new stream more than 60 s old
    "future_timestamp",  # MAVLink: signing timestamp more than 60 s ahead of the clock
    "impersonation",  # the payload names another sender than its key (sysid or vehicle_id)
    "unknown_sysid",  # MAVLink from a system id that is not a vehicle of the swarm
    "degenerate",  # zero, singular, non-positive-definite or huge covariance; absurd values
    "stamp_out_of_range",  # far in the past or the future of the receiver's sim time
    "unexpected",  # a valid message of a kind this key does not carry
    "inbox_full",  # dropped at the bound of an inbox
    "held_full",  # dropped at the bound of the link-fault stage's held packets
    "pending_full",  # dropped at the bound of the ground station's pending scores
    "garbage_frame",  # a camera frame the front end cannot use: wrong shape or type, empty, black, uniform
    "no_visual_motion",  # visual odometry found no motion between two frames (too few matches, degenerate)
)
_INDEX = {reason: i for i, reason in enumerate(REASONS)}
Reject = Callable[[str, str, str], None]  # Rejections.reject(reason, where, detail), as handed to a part
MAX_LOGGED = 1000  # distinct (reason, where) pairs logged; past that, rejections are only counted


class Rejections:
    """Thread-safe counts by reason; the first rejection of each (reason, where) is logged (the first
    ``MAX_LOGGED`` such pairs: hostile traffic with ever new keys must not flood the log)."""

    def __init__(self, log: logging.Logger, owner: str) -> None:
        self._log, self._owner = log, owner
        self._lock = threading.Lock()
        self.counts: Counter[str] = Counter()
        self._logged: set[tuple[str, str]] = set()
        self.on_first: Callable[[str, str, str], None] | None = None  # (reason, where, detail) of each logged one

    def reject(self, reason: str, where: str, detail: str = "", count: int = 1) -> None:
        if reason not in _INDEX:
            raise ValueError(f"unknown rejection reason {reason!r}")
        with self._lock:
            self.counts[reason] += count
            first = (reason, where) not in self._logged and len(self._logged) < MAX_LOGGED
            if first:
                self._logged.add((reason, where))
        if first:
            self._log.warning(
                "%s rejected input (%s) on %s: %s; further ones are only counted",
                self._owner,
                reason,
                where[:120],
                detail[:300] or "-",
            )
            if self.on_first is not None:
                self.on_first(reason, where[:120], detail[:300])

    def as_counts(self) -> tuple[int, ...]:
        with self._lock:
            return tuple(self.counts.get(reason, 0) for reason in REASONS)

    @property
    def total(self) -> int:
        with self._lock:
            return sum(self.counts.values())


def counts_to_dict(counts: tuple[int, ...]) -> dict[str, int]:
    """A counts tuple (order of REASONS) as {reason: count}, zero counts left out."""
    return {reason: n for reason, n in zip(REASONS, counts) if n}
