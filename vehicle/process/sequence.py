"""Observed link quality of the sensor feeds: samples lost, from gaps in each feed's sequence numbers."""

from __future__ import annotations

WINDOW = 10_000  # sequence numbers remembered per topic to recognise duplicates


class SequenceTracker:
    """Per topic, the first and highest sequence number seen and how many distinct ones arrived."""

    def __init__(self) -> None:
        self._first: dict[str, int] = {}
        self._highest: dict[str, int] = {}
        self._distinct: dict[str, int] = {}
        self._recent: dict[str, set[int]] = {}

    def see(self, topic: str, seq: int) -> None:
        recent = self._recent.get(topic)
        if recent is None:
            recent = self._recent[topic] = set()
            self._first[topic] = self._highest[topic] = seq
            self._distinct[topic] = 0
        elif seq in recent:
            return
        recent.add(seq)
        if seq < self._first[topic]:
            self._first[topic] = seq
        elif seq > self._highest[topic]:
            self._highest[topic] = seq
        self._distinct[topic] += 1
        if len(recent) > 2 * WINDOW:
            floor = self._highest[topic] - WINDOW
            self._recent[topic] = {s for s in recent if s >= floor}

    def see_range(self, topic: str, seq0: int, count: int) -> None:
        """``see`` for ``count`` consecutive sequence numbers from ``seq0`` (a batch's block), at once
        while no pruning falls inside the block (else one by one, for the same outcome)."""
        recent = self._recent.get(topic)
        if count <= 0 or recent is None or len(recent) + count > 2 * WINDOW:
            for seq in range(seq0, seq0 + count):
                self.see(topic, seq)
            return
        before = len(recent)
        recent.update(range(seq0, seq0 + count))
        self._distinct[topic] += len(recent) - before
        self._first[topic] = min(self._first[topic], seq0)
        self._highest[topic] = max(self._highest[topic], seq0 + count - 1)

    @property
    def lost(self) -> int:
        """Samples missing between the first and highest sequence number, summed over topics."""
        return sum(self._highest[t] - self._first[t] + 1 - self._distinct[t] for t in self._first)

    def received(self, topic: str) -> int:
        return self._distinct.get(topic, 0)
