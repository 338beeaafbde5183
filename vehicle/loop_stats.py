"""Loop timing statistics: overruns, wake-up jitter and cycle compute time (wall clock)."""

from __future__ import annotations

from collections import deque

import numpy as np


class LoopStats:
    """Keeps the last ``window`` samples of jitter and cycle time (us) and counts overruns."""

    def __init__(self, window: int = 20_000) -> None:
        self.cycles = 0
        self.overruns = 0
        self._jitter_us: deque[float] = deque(maxlen=window)
        self._cycle_us: deque[float] = deque(maxlen=window)

    def record(self, *, jitter_us: float, cycle_us: float, overran: bool) -> None:
        self.cycles += 1
        self.overruns += int(overran)
        self._jitter_us.append(jitter_us)
        self._cycle_us.append(cycle_us)

    @staticmethod
    def _p99(samples: deque[float]) -> float:
        return float(np.percentile(samples, 99)) if samples else 0.0

    def jitter_p99_us(self) -> float:
        return self._p99(self._jitter_us)

    def cycle_p99_us(self) -> float:
        return self._p99(self._cycle_us)
