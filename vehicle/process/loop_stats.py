"""Loop timing statistics: overruns, wake-up jitter and cycle compute time (wall clock)."""

from __future__ import annotations

import numpy as np


class _Ring:
    """The last ``size`` samples in a preallocated array (a percentile is then one partition, with
    no conversion of a Python container; it is asked for at every status, once a sim second)."""

    def __init__(self, size: int) -> None:
        self._values = np.empty(size)
        self._count = 0

    def append(self, value: float) -> None:
        self._values[self._count % len(self._values)] = value
        self._count += 1

    def p99(self) -> float:
        """The 99th percentile, interpolated linearly between ranks (numpy's default method), by one
        partition: np.percentile's first call costs ~6 ms, which every vehicle paid in the same cycle."""
        filled = self._values[: min(self._count, len(self._values))]
        if not len(filled):
            return 0.0
        position = 0.99 * (len(filled) - 1)
        low = int(position)
        high = min(low + 1, len(filled) - 1)
        ranked = np.partition(filled, (low, high))
        return float(ranked[low] + (ranked[high] - ranked[low]) * (position - low))


class LoopStats:
    """Keeps the last ``window`` samples of jitter and cycle time (us) and counts overruns."""

    def __init__(self, window: int = 20_000) -> None:
        self.cycles = 0
        self.overruns = 0
        self._jitter_us = _Ring(window)
        self._cycle_us = _Ring(window)

    def record(self, *, jitter_us: float | None, cycle_us: float, overran: bool) -> None:
        """One cycle; ``jitter_us`` None for a cycle that had no deadline (realtime's first)."""
        self.cycles += 1
        self.overruns += int(overran)
        if jitter_us is not None:
            self._jitter_us.append(jitter_us)
        self._cycle_us.append(cycle_us)

    def jitter_p99_us(self) -> float:
        return self._jitter_us.p99()

    def cycle_p99_us(self) -> float:
        return self._cycle_us.p99()
