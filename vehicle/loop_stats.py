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
        filled = self._values[:min(self._count, len(self._values))]
        return float(np.percentile(filled, 99)) if len(filled) else 0.0


class LoopStats:
    """Keeps the last ``window`` samples of jitter and cycle time (us) and counts overruns."""

    def __init__(self, window: int = 20_000) -> None:
        self.cycles = 0
        self.overruns = 0
        self._jitter_us = _Ring(window)
        self._cycle_us = _Ring(window)

    def record(self, *, jitter_us: float, cycle_us: float, overran: bool) -> None:
        self.cycles += 1
        self.overruns += int(overran)
        self._jitter_us.append(jitter_us)
        self._cycle_us.append(cycle_us)

    def jitter_p99_us(self) -> float:
        return self._jitter_us.p99()

    def cycle_p99_us(self) -> float:
        return self._cycle_us.p99()
