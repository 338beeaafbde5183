"""The fusion horizon: measurements reach the estimator in stamp order even when they arrive late.

Each loop cycle at time t applies every buffered measurement stamped <= t, lets the estimator run
its per-cycle checks, and keeps a checkpoint (a copy of the estimator) for t. A measurement that
arrives after the cycle covering its stamp is *late*: within the horizon, the estimator goes back to
the newest checkpoint before it and replays everything since, in order (retrodiction by replay, as
out-of-sequence filters do). Older than the horizon: dropped and counted. A second copy of a
measurement (same topic and sequence number) is ignored and counted.
"""

from __future__ import annotations

import bisect
import heapq
import itertools
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable, Protocol


class Estimator(Protocol):
    def handle(self, msg: Any) -> None: ...
    def tick(self, stamp_us: int) -> None: ...
    def snapshot(self) -> Any: ...
    def restore(self, snapshot: Any) -> None: ...


@dataclass
class FusionCounters:
    late_fused: int = 0
    dropped_stale: int = 0
    duplicates: int = 0
    replays: int = 0


class FusionHorizon:
    """Orders measurements for one estimator; ``horizon_us`` is how late a measurement may be."""

    def __init__(self, estimator: Estimator, *, horizon_us: int) -> None:
        self.estimator, self.horizon_us = estimator, horizon_us
        self.counters = FusionCounters()
        self._pending: list[tuple[int, int, str, Any]] = []   # heap: (stamp, arrival, topic, msg)
        self._late: list[tuple[int, int, str, Any]] = []
        self._applied: list[tuple[int, int, str, Any]] = []   # sorted, newer than the oldest checkpoint
        self._checkpoints: deque[tuple[int, Any]] = deque()   # (cycle time, estimator snapshot after it)
        if horizon_us > 0:
            self._checkpoints.append((-1, estimator.snapshot()))  # before anything: stamp-0 data can be late
        self._seen: dict[tuple[str, int], int] = {}           # (topic, seq) -> stamp
        self._arrival = itertools.count()
        self.cycle_us: int | None = None                       # time of the last cycle

    def push(self, topic: str, msg: Any) -> None:
        """Buffer one decoded measurement (it has ``stamp_us`` and ``seq``)."""
        ident = (topic, msg.seq)
        if ident in self._seen:
            self.counters.duplicates += 1
            return
        self._seen[ident] = msg.stamp_us
        entry = (msg.stamp_us, next(self._arrival), topic, msg)
        if self.cycle_us is None or msg.stamp_us > self.cycle_us:
            heapq.heappush(self._pending, entry)
        elif msg.stamp_us >= self.cycle_us - self.horizon_us and self._checkpoint_before(msg.stamp_us) is not None:
            self._late.append(entry)
        else:
            self.counters.dropped_stale += 1

    def cycle(self, t_us: int, on_cycle: Callable[[int], None] | None = None) -> None:
        """Fuse everything stamped <= ``t_us`` (replaying for late arrivals), then checkpoint t_us."""
        if self._late:
            self._replay()
        while self._pending and self._pending[0][0] <= t_us:
            self._apply(heapq.heappop(self._pending))
        self.estimator.tick(t_us)
        if on_cycle is not None:
            on_cycle(t_us)
        self._checkpoint(t_us)
        self.cycle_us = t_us

    def _apply(self, entry: tuple[int, int, str, Any]) -> None:
        self.estimator.handle(entry[3])
        self._applied.append(entry)

    def _checkpoint(self, t_us: int) -> None:
        if self.horizon_us <= 0:
            self._applied.clear()
            return
        self._checkpoints.append((t_us, self.estimator.snapshot()))
        while len(self._checkpoints) > 1 and self._checkpoints[1][0] < t_us - self.horizon_us:
            self._checkpoints.popleft()
        oldest = self._checkpoints[0][0]
        cut = bisect.bisect_right([e[0] for e in self._applied], oldest)
        del self._applied[:cut]
        self._seen = {k: s for k, s in self._seen.items() if s >= oldest} if len(self._seen) > 4096 else self._seen

    def _checkpoint_before(self, stamp_us: int) -> int | None:
        """Index of the newest checkpoint strictly before ``stamp_us`` (None if there is none)."""
        times = [t for t, _ in self._checkpoints]
        i = bisect.bisect_left(times, stamp_us) - 1
        return i if i >= 0 else None

    def _replay(self) -> None:
        """Go back to the checkpoint before the oldest late measurement and fuse everything again."""
        late = sorted(self._late)
        self._late.clear()
        i = self._checkpoint_before(late[0][0])
        if i is None:  # its checkpoint aged out since the push
            self.counters.dropped_stale += len(late)
            return
        self.counters.replays += 1
        self.counters.late_fused += len(late)
        start_us, snapshot = self._checkpoints[i]
        kept = list(itertools.islice(self._checkpoints, 0, i + 1))
        later_cycles = [t for t, _ in itertools.islice(self._checkpoints, i + 1, None)]
        redo = sorted([e for e in self._applied if e[0] > start_us] + late)
        self._applied = [e for e in self._applied if e[0] <= start_us]
        self._checkpoints = deque(kept)
        self.estimator.restore(snapshot)
        k = 0
        for t_us in later_cycles:
            while k < len(redo) and redo[k][0] <= t_us:
                self._apply(redo[k])
                k += 1
            self.estimator.tick(t_us)
            self._checkpoints.append((t_us, self.estimator.snapshot()))
        for entry in redo[k:]:
            heapq.heappush(self._pending, entry)
