"""Link faults, applied by a receiving process's bus layer to what arrives (pure, no bus).

Every arriving packet is offered with its key, sending endpoint, topic and sim-time stamp. Each
active fault that selects it may drop it (random or Gilbert-Elliott loss), duplicate it, or hold it
back (delay with jitter, reordering). Selected packets come out of :meth:`LinkFaultStage.release`
once the receiver's sim time reaches ``stamp + delay``, in that order.

Reproducible: every random draw is a hash of (seed, fault name, key, n, slot), where n counts the
packets that arrived on that key. Zenoh keeps order within a key, so n names the same packet in
every run; decisions do not depend on wall time or on how keys interleave.
"""

from __future__ import annotations

import fnmatch
import hashlib
import heapq
import itertools
import math
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bus.faults import Delay, Duplicate, LinkFault, Loss, Reorder
from bus.topics import Topic

PARETO_SHAPE = 3.0
MAX_HELD = 200_000


def uniform(seed: int, *parts: object) -> float:
    """A reproducible uniform draw in [0, 1) named by ``parts``."""
    digest = hashlib.blake2b("|".join(map(str, (seed, *parts))).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little") / 2.0**64


def delay_sample_s(fault: Delay, u1: float, u2: float) -> float:
    """One delay (s, >= 0) from two uniforms, by the fault's distribution."""
    d, j = fault.delay_s, fault.jitter_s
    if j == 0.0:
        return d
    if fault.distribution == "uniform":
        return max(0.0, d - j + 2.0 * j * u1)
    if fault.distribution == "normal":  # Box-Muller
        z = math.sqrt(-2.0 * math.log(1.0 - u1)) * math.cos(2.0 * math.pi * u2)
        return max(0.0, d + j * z)
    low = max(0.0, d - j)  # pareto (Lomax): minimum `low`, mean d, shape PARETO_SHAPE
    scale = (d - low) * (PARETO_SHAPE - 1.0)
    return low + scale * ((1.0 - u1) ** (-1.0 / PARETO_SHAPE) - 1.0)


@dataclass(frozen=True)
class Arrival:
    key: str
    src: str
    topic: Topic
    stamp_us: int
    item: Any


class LinkFaultStage:
    """The link faults of one receiving endpoint (``v3``, ``gs``, ...)."""

    def __init__(self, receiver: str, *, seed: int, faults: tuple = ()) -> None:
        self.receiver, self.seed = receiver, seed
        self.faults: tuple[LinkFault, ...] = ()
        self.set_plan(faults)
        self._arrivals: Counter[str] = Counter()  # per key: bounded by the keys a receiver listens to
        self._bad: dict[tuple[str, str], bool] = {}  # Gilbert-Elliott state per (fault, key)
        self._held: list[tuple[int, int, Arrival]] = []
        self._order = itertools.count()
        self.dropped: Counter[str] = Counter()
        self.duplicated: Counter[str] = Counter()
        self.delayed: Counter[str] = Counter()
        self.dropped_full = 0  # copies refused at MAX_HELD

    def set_plan(self, faults: tuple) -> None:
        """Keep the plan's link faults that can select traffic to this receiver."""
        self.faults = tuple(f for f in faults if isinstance(f, LinkFault) and fnmatch.fnmatchcase(self.receiver, f.dst))

    def untouched(self, key: str, count: int = 1) -> bool:
        """True when no fault of the plan can select traffic to this receiver: ``count`` arrivals on
        ``key`` are then counted as offered (later faults draw for them as they would have) and pass
        as they are, without being offered one by one."""
        if self.faults:
            return False
        self._arrivals[key] += count
        return True

    def offer(self, arrival: Arrival) -> list[Any]:
        """Take one arriving packet. One that no active fault selects is returned at once; otherwise
        its copies (0, 1 or 2) come out of :meth:`release` at stamp + delay, in that order, so that
        what a receiver sees never depends on how arrivals interleave with its clock."""
        n = self._arrivals[arrival.key]
        self._arrivals[arrival.key] = n + 1
        t_s = arrival.stamp_us * 1e-6
        active = [f for f in self.faults if f.active(t_s) and f.selects(arrival.src, self.receiver, arrival.topic)]
        if not active:
            return [arrival.item]
        extra_us = [0]
        for fault in active:
            tag = (fault.name, arrival.key, n)
            if isinstance(fault, Loss) and self._lost(fault, arrival.key, n):
                self.dropped[fault.name] += 1
                return []
            if isinstance(fault, Duplicate) and uniform(self.seed, *tag, "dup") < fault.percent / 100.0:
                self.duplicated[fault.name] += 1
                extra_us = extra_us + extra_us
            elif isinstance(fault, Delay):
                extra_us = [
                    e
                    + round(
                        1e6
                        * delay_sample_s(
                            fault, uniform(self.seed, *tag, "d", k, 1), uniform(self.seed, *tag, "d", k, 2)
                        )
                    )
                    for k, e in enumerate(extra_us)
                ]
                self.delayed[fault.name] += len(extra_us)
            elif isinstance(fault, Reorder) and uniform(self.seed, *tag, "reorder") < fault.percent / 100.0:
                extra_us = [e + round(1e6 * fault.gap_s) for e in extra_us]
                self.delayed[fault.name] += len(extra_us)
        for e in extra_us:  # even undelayed copies wait for release(): delivery follows stamps, not arrival
            if len(self._held) < MAX_HELD:
                heapq.heappush(self._held, (arrival.stamp_us + e, next(self._order), arrival))
            else:
                self.dropped_full += 1
        return []

    def _lost(self, fault: Loss, key: str, n: int) -> bool:
        u = uniform(self.seed, fault.name, key, n, "loss")
        p = fault.percent / 100.0
        if fault.burst is None or p in (0.0, 1.0):
            return u < p
        exit_bad = 1.0 / fault.burst  # mean burst length 1 / r; long-run loss p = q / (q + r)
        enter_bad = min(1.0, exit_bad * p / (1.0 - p))
        was_bad = self._bad.get((fault.name, key), False)
        bad = u >= exit_bad if was_bad else u < enter_bad
        self._bad[(fault.name, key)] = bad
        return bad

    def release(self, now_us: int, ready: Callable[[Arrival, int], bool] | None = None) -> list[Any]:
        """Held items due at or before ``now_us``, in due order. ``ready(arrival, due_us)`` may keep an
        item back: a receiver that cannot tell whether earlier packets of a stream are still on
        their way (the ground station) releases an item only once its stream has passed its due time."""
        out, waiting = [], []
        while self._held and self._held[0][0] <= now_us:
            entry = heapq.heappop(self._held)
            if ready is None or ready(entry[2], entry[0]):
                out.append(entry[2].item)
            else:
                waiting.append(entry)
        for entry in waiting:
            heapq.heappush(self._held, entry)
        return out

    def held_min_stamp(self, key: str | None = None) -> int | None:
        """The oldest stamp still held (on ``key``, or on any key); None when nothing is held."""
        stamps = [a.stamp_us for _, _, a in self._held if key is None or a.key == key]
        return min(stamps) if stamps else None

    @property
    def held(self) -> int:
        return len(self._held)
