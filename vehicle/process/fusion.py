"""The fusion horizon: measurements reach the estimator in stamp order even when they arrive late.

Each loop cycle at time t applies every buffered measurement stamped <= t, then runs the estimator's
cycle (propagation, health checks, divergence recovery). A measurement that arrives after the cycle
covering its stamp is *late*: within the horizon, the estimator goes back to the newest checkpoint
before it and replays everything since, in order (retrodiction by replay, as out-of-sequence filters
do). Older than the horizon: dropped and counted. A second copy of a measurement (same topic and
sequence number) is ignored and counted.

Checkpoints cost a copy of the estimator, which for a SLAM map is an n x n covariance, so they are
taken only where a late measurement can land: ``expect(stamp)`` asks for one just before ``stamp``
(the link-fault stage holding a delayed packet, a ranging measurement waiting for its neighbour's
broadcast where that can come after later cycles: realtime, link faults); ``every_cycles`` adds one
every N cycles for links whose lateness nobody can foresee (realtime). Besides, there is one at
least every horizon: what is kept for replays (everything since the newest checkpoint older than
the horizon) stays bounded when nothing is announced. A checkpoint
with bound b holds the state after every measurement stamped < b and every cycle < b.

A cycle may also be postponed (``postpone``: lockstep, while a ranging fix it will fuse is still on
its way and nothing is sent at it): a measurement that arrives before it runs is late but needs no
replay. And a measurement of an ``after_cycle`` topic (the vehicles' ranging fixes) stamped
at the time of the last cycle, arriving after that cycle ran, is fused right after it, before
anything later, instead of replaying it: the cycle's estimate went out without the fix by design
(the V2V broadcast it pairs with), and what the cycle does at its own stamp (a propagation by zero,
the GNSS monitor's clock, the divergence check) does not touch what a fix updates, so the mean and
covariance are those of the replay; only the divergence check sees the state before the fix.
"""

from __future__ import annotations

import bisect
import heapq
import itertools
import logging
from collections import Counter, deque
from dataclasses import dataclass
from functools import partial
from typing import Any

from bus.topics import Topic
from vehicle.estimators.parts import Replayable
from vehicle.process.input_runs import InputRun

log = logging.getLogger("swarmloc.vehicle")
MAX_PENDING = 200_000
MAX_SEEN = 4_096  # (topic, seq) pairs remembered; pruned to the horizon beyond (a 10-minute soak grew 18 MB at 100k)


@dataclass
class FusionCounters:
    late_fused: int = 0
    dropped_stale: int = 0
    duplicates: int = 0
    replays: int = 0
    checkpoints: int = 0
    failed: int = 0  # measurements the estimator could not apply (counted, skipped)
    dropped_full: int = 0  # refused at the bound of the pending buffer


Entry = tuple[int, int, Topic, Any]  # (stamp, arrival order, topic, message or InputRun)
RunSample = tuple[int, int, Topic, InputRun, int]  # (stamp, arrival order, topic, run, index in it)


class FusionHorizon:
    """Orders measurements for one estimator; ``horizon_us`` is how late a measurement may be."""

    def __init__(
        self,
        estimator: Replayable,
        *,
        horizon_us: int,
        every_cycles: int = 0,
        after_cycle: frozenset[Topic] = frozenset(),
    ) -> None:
        self.estimator, self.horizon_us, self.every_cycles = estimator, horizon_us, every_cycles
        self.after_cycle = after_cycle  # topics fused right after the cycle at their stamp (module docstring)
        self.counters = FusionCounters()
        self._pending: list[Entry] = []
        self._late: list[Entry] = []
        self._applied: list[Entry] = []  # in order, stamped >= the oldest checkpoint's bound
        self._checkpoints: deque[tuple[int, Any]] = deque()  # (bound, snapshot), bounds increasing
        self._cycles: deque[int] = deque()  # cycles run since the oldest checkpoint's bound
        self._expected: list[int] = []  # heap of stamps that want a checkpoint before them
        self._outstanding: Counter[int] = Counter()  # announced late measurements not arrived yet, by stamp
        self._periodic: set[int] = set()  # bounds of the every_cycles checkpoints
        self._seen: dict[tuple[Topic, int], int] = {}  # (topic, seq) -> stamp
        self._arrival = 0  # the next arrival number
        self.cycle_us: int | None = None  # time of the last cycle
        self.due_us: int | None = None  # time of the last cycle due: the last run, or one postponed since
        if horizon_us > 0:
            self._checkpoint(0)

    def reserve(self, count: int) -> int:
        """The first of ``count`` arrival numbers for measurements to be pushed with them (a batch's)."""
        first, self._arrival = self._arrival, self._arrival + count
        return first

    def push(self, topic: Topic, msg: Any, arrival: int | None = None) -> None:
        """Buffer one decoded measurement (it has ``stamp_us`` and ``seq``); ``arrival``: its number
        from :meth:`reserve` (else the next)."""
        if arrival is None:
            arrival = self.reserve(1)
        ident = (topic, msg.seq)
        if ident in self._seen:
            self.counters.duplicates += 1
            return
        if len(self._pending) >= MAX_PENDING:
            self.counters.dropped_full += 1
            return
        self._seen[ident] = msg.stamp_us
        entry = (msg.stamp_us, arrival, topic, msg)
        at_last_cycle = msg.stamp_us == self.cycle_us and topic in self.after_cycle
        if self.cycle_us is None or msg.stamp_us > self.cycle_us or at_last_cycle:
            if self.due_us is not None and msg.stamp_us <= self.due_us:  # late, but its cycle has not run
                self.counters.late_fused += 1
                self._arrived_before_checkpoint(msg.stamp_us)
            heapq.heappush(self._pending, entry)
        elif (
            msg.stamp_us >= self.cycle_us - self.horizon_us and self._checkpoint_at_or_before(msg.stamp_us) is not None
        ):
            self._late.append(entry)
            if self._outstanding[msg.stamp_us] > 0:
                self._outstanding[msg.stamp_us] -= 1
        else:
            self.counters.dropped_stale += 1

    def push_run(self, run: InputRun) -> None:
        """Buffer a run of input samples (vehicle.process.input_runs), numbered from :meth:`reserve`. A run
        whose samples are all new and later than every cycle due waits as one entry; any other goes
        one message at a time, as :meth:`push` takes them."""
        n = len(run.stamps)
        fresh = (self.cycle_us is None or run.stamps[0] > self.cycle_us) and (
            self.due_us is None or run.stamps[0] > self.due_us
        )
        if not n or not fresh or len(self._pending) >= MAX_PENDING or not self._seen.keys().isdisjoint(run.idents):
            for i in range(n):
                self.push(run.idents[i][0], run.message(i), run.arrivals[i])
            return
        self._seen.update(zip(run.idents, run.stamps))
        heapq.heappush(self._pending, (run.stamps[0], run.arrivals[0], run.idents[0][0], run))

    def expect(self, stamp_us: int) -> None:
        """A measurement stamped ``stamp_us`` will arrive late: keep a checkpoint just before it."""
        if self.horizon_us > 0 and (self.cycle_us is None or stamp_us > self.cycle_us):
            heapq.heappush(self._expected, stamp_us)
            self._outstanding[stamp_us] += 1

    def postpone(self, t_us: int) -> None:
        """The cycle at ``t_us`` is due but will run later (before any later one): a measurement
        stamped at or before it that arrives meanwhile is late, and is fused in stamp order when the
        cycle runs, with no replay."""
        self.due_us = t_us if self.due_us is None else max(self.due_us, t_us)

    def cycle(self, t_us: int) -> None:
        """Fuse everything stamped <= ``t_us`` (replaying for late arrivals), then run the cycle."""
        self.due_us = t_us if self.due_us is None else max(self.due_us, t_us)
        if self._late:
            self._replay()
        while self._pending and self._pending[0][0] <= t_us:
            entry = heapq.heappop(self._pending)
            if len(entry) == 4 and type(entry[3]) is InputRun:
                self._apply_run(entry[3], t_us)
                continue
            self._checkpoints_due(entry[0])
            self._apply(entry)
        self._checkpoints_due(t_us)
        self._run_cycle(t_us)
        self.cycle_us = t_us
        if self.every_cycles and len(self._cycles) % self.every_cycles == 0:
            self._checkpoint(t_us + 1)
            self._periodic.add(t_us + 1)
        elif self.horizon_us > 0 and self._checkpoints[-1][0] <= t_us - self.horizon_us:
            self._checkpoint(t_us + 1)  # at least one a horizon, so that the history kept stays bounded
        self._prune(t_us)

    def _arrived_before_checkpoint(self, stamp_us: int) -> None:
        """An announced late measurement came before anything from its stamp on was applied: the
        checkpoint kept for it is not needed."""
        if self._outstanding[stamp_us] > 0:
            self._outstanding[stamp_us] -= 1
            if stamp_us in self._expected:
                self._expected.remove(stamp_us)
                heapq.heapify(self._expected)

    def _checkpoints_due(self, stamp_us: int) -> None:
        """Before anything stamped ``stamp_us`` is applied: a checkpoint with bound s for the earliest
        expected stamp s <= ``stamp_us`` (nothing stamped >= s has been applied yet)."""
        first = None
        while self._expected and self._expected[0] <= stamp_us:
            s = heapq.heappop(self._expected)
            first = s if first is None else first
        if first is not None:
            self._checkpoint(first)

    def _apply(self, entry: Entry | RunSample) -> None:
        try:
            if len(entry) == 5:  # one sample of a run (a replay)
                run, i = entry[3], entry[4]
                self.estimator.handle_row(entry[2], entry[0], run.rows[i], partial(run.message, i))
            else:
                self.estimator.handle(entry[3])
        except (ArithmeticError, ValueError, IndexError) as exc:  # numpy's LinAlgError is a ValueError
            self.counters.failed += 1
            log.warning("estimator could not apply %s at %d us: %s: %s", entry[2], entry[0], type(exc).__name__, exc)
        self._applied.append(entry)

    def _apply_run(self, run: InputRun, t_us: int) -> None:
        """Apply a run's samples up to ``t_us`` that come before the next pending entry (by stamp, then
        arrival), each as :meth:`_apply` would one message; the rest waits as the run's entry."""
        nxt = self._pending[0] if self._pending else None
        stamps, arrivals, n, i = run.stamps, run.arrivals, len(run.stamps), run.next
        while i < n and stamps[i] <= t_us and (nxt is None or (stamps[i], arrivals[i]) < (nxt[0], nxt[1])):
            if self._expected:
                self._checkpoints_due(stamps[i])
            self._apply((stamps[i], arrivals[i], run.idents[i][0], run, i))
            i += 1
        run.next = i
        if i < n:
            heapq.heappush(self._pending, (stamps[i], arrivals[i], run.idents[i][0], run))

    def _run_cycle(self, t_us: int) -> None:
        self.estimator.cycle(t_us)
        self._cycles.append(t_us)

    def _checkpoint(self, bound_us: int) -> None:
        if self.horizon_us <= 0 or (self._checkpoints and self._checkpoints[-1][0] >= bound_us):
            return
        self._checkpoints.append((bound_us, self.estimator.snapshot()))
        self.counters.checkpoints += 1

    def _checkpoint_at_or_before(self, stamp_us: int) -> int | None:
        """Index of the newest checkpoint with bound <= ``stamp_us`` (None if there is none)."""
        for i in range(len(self._checkpoints) - 1, -1, -1):
            if self._checkpoints[i][0] <= stamp_us:
                return i
        return None

    def _prune(self, t_us: int) -> None:
        """Keep the newest checkpoint older than the horizon and everything after it."""
        if self.horizon_us <= 0:
            self._applied.clear()
            self._cycles.clear()
            return
        limit = t_us - self.horizon_us
        while len(self._checkpoints) > 1 and self._checkpoints[1][0] <= limit:
            self._periodic.discard(self._checkpoints.popleft()[0])
        oldest = self._checkpoints[0][0]
        if len(self._outstanding) > 64:  # announced but never came (lost on the way): forget them
            self._outstanding = Counter({s: n for s, n in self._outstanding.items() if n > 0 and s >= limit})
        if self._applied and self._applied[0][0] < oldest:  # applied in stamp order
            del self._applied[: bisect.bisect_left(self._applied, oldest, key=_stamp)]
        while self._cycles and self._cycles[0] < oldest:
            self._cycles.popleft()
        if len(self._seen) > MAX_SEEN:
            self._seen = {k: s for k, s in self._seen.items() if s >= limit}

    def _replay(self) -> None:
        """Go back to the checkpoint before the oldest late measurement and fuse everything again,
        re-taking the later checkpoints that can still be needed: periodic ones, and those of
        announced measurements that have not arrived yet."""
        late = sorted(self._late)
        self._late.clear()
        i = self._checkpoint_at_or_before(late[0][0])
        if i is None:  # its checkpoint aged out since the push
            self.counters.dropped_stale += len(late)
            return
        self.counters.replays += 1
        self.counters.late_fused += len(late)
        bound, snapshot = self._checkpoints[i]
        rebuild = [
            b
            for b, _ in itertools.islice(self._checkpoints, i + 1, None)
            if b in self._periodic or self._outstanding[b] > 0
        ]
        cycles = [t for t in self._cycles if t >= bound]
        redo = sorted([e for e in self._applied if e[0] >= bound] + late)
        self._applied = [e for e in self._applied if e[0] < bound]
        self._checkpoints = deque(itertools.islice(self._checkpoints, 0, i + 1))
        self._cycles = deque(t for t in self._cycles if t < bound)
        self.estimator.restore(snapshot)
        for b in rebuild:
            heapq.heappush(self._expected, b)
        k = 0
        for t_us in cycles:
            while k < len(redo) and redo[k][0] <= t_us:
                self._checkpoints_due(redo[k][0])
                self._apply(redo[k])
                k += 1
            self._checkpoints_due(t_us)
            self._run_cycle(t_us)
            if t_us + 1 in rebuild:
                self._checkpoint(t_us + 1)
        for entry in redo[k:]:
            heapq.heappush(self._pending, entry)


def _stamp(entry: Entry) -> int:
    return entry[0]
