"""Bounded mailboxes: zenoh callbacks only enqueue, one loop thread takes.

A Mailbox has lanes, each bounded in items and bytes; ``get`` takes from the first non-empty lane
in the order the lanes were made, so a flood on one lane (say, neighbours' broadcasts) can neither
delay nor crowd out another (the world's feed). What a full lane refuses is counted, never queued.
A taker waiting for items from particular senders may have one lane wake it only once each of them
has sent something (``get``'s ``quiet_lane`` and ``senders_by_key``): every wake-up is a context
switch and a cold cache.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Oversized:
    """Stands in for a payload over its size cap: the callback never copied it."""

    key: str
    size: int


def _size(item: Any) -> int:
    payload = getattr(item, "payload", None)
    return len(payload) if isinstance(payload, (bytes, bytearray)) else 64


class Lane:
    """One bounded FIFO of a Mailbox; ``put`` is safe from any thread."""

    def __init__(self, box: Mailbox, name: str, max_items: int, max_bytes: int) -> None:
        self.box, self.name, self.max_items, self.max_bytes = box, name, max_items, max_bytes
        self.items: deque = deque()
        self.bytes = 0
        self.dropped = 0

    def put(self, item: Any) -> bool:
        """Queue ``item``; False (and counted) when the lane is full."""
        size = _size(item)
        with self.box.cond:
            if len(self.items) >= self.max_items or self.bytes + size > self.max_bytes:
                self.dropped += 1
                return False
            self.items.append((item, size))
            self.bytes += size
            if self.box.wakes(self, item):
                self.box.cond.notify()
        return True


class Mailbox:
    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.lanes: list[Lane] = []
        # while a taker waits on a quiet lane: (lane, sender per key, senders not heard from yet)
        self._quiet: tuple[Lane, Mapping[str, Hashable], set[Hashable]] | None = None

    def lane(self, name: str, *, max_items: int = 100_000, max_bytes: int = 64 << 20) -> Lane:
        lane = Lane(self, name, max_items, max_bytes)
        self.lanes.append(lane)
        return lane

    def _take(self) -> Any:
        for lane in self.lanes:
            if lane.items:
                return self._pop(lane)
        return None

    @staticmethod
    def _pop(lane: Lane) -> Any:
        item, size = lane.items.popleft()
        lane.bytes -= size
        return item

    def wakes(self, lane: Lane, item: Any) -> bool:
        """Whether ``item``, just queued on ``lane``, wakes a waiting taker (called under ``cond``)."""
        quiet = self._quiet
        if quiet is None or quiet[0] is not lane:
            return True
        _, senders, pending = quiet
        sender = senders.get(getattr(item, "key", None))
        if sender is None:  # not from a sender awaited
            return False
        pending.discard(sender)
        return not pending

    def get(
        self,
        timeout: float | None = None,
        *,
        quiet_lane: Lane | None = None,
        senders_by_key: Mapping[str, Hashable] | None = None,
    ) -> Any:
        """The next item by lane order, waiting up to ``timeout`` seconds; None when nothing came. While
        it waits, the items of ``quiet_lane`` wake it only once one has come from every sender in
        ``senders_by_key`` (key an item comes on -> its sender, never None; empty: they never wake it); they are
        queued meanwhile and taken in lane order once it is awake. Items of other lanes wake it."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self.cond:
            while True:
                item = self._take()
                if item is not None:
                    return item
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return None
                if quiet_lane is not None:
                    senders = senders_by_key or {}
                    self._quiet = (quiet_lane, senders, set(senders.values()))
                try:
                    self.cond.wait(remaining)
                finally:
                    self._quiet = None

    def get_nowait(self) -> Any:
        with self.cond:
            return self._take()

    def get_nowait_from(self, lane: Lane) -> Any:
        """The next item of ``lane`` only (None when it is empty)."""
        with self.cond:
            return self._pop(lane) if lane.items else None

    def empty(self) -> bool:
        with self.cond:
            return not any(lane.items for lane in self.lanes)

    def dropped(self) -> int:
        """Items refused by full lanes since the start."""
        with self.cond:
            return sum(lane.dropped for lane in self.lanes)
