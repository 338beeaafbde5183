"""What every benchmark returns: rows with a measured value, its unit and the target it is held to."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass


@dataclass(frozen=True)
class Row:
    benchmark: str
    case: str
    metric: str
    value: float | None
    unit: str
    target: str  # e.g. "<= 20 us", ">= 20x", or "-" when the row is context only
    met: bool | None  # None: no target
    details: dict | None = None  # everything else measured for this case

    def as_dict(self) -> dict:
        return asdict(self)


def per_call_us(body: Callable[[], object], *, calls: int, repeats: int = 5) -> float:
    """Best-of-``repeats`` mean wall time of one call in microseconds (the best run is the least disturbed
    on a shared machine)."""
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(calls):
            body()
        best = min(best, (time.perf_counter() - start) / calls)
    return best * 1e6
