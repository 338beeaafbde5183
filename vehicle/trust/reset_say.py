"""The believed neighbours' say on the vehicle's own GNSS position resets: a spoofed receiver's fixes
agree with each other and pass the reset's own tests, but not with neighbours that range the
vehicle where it is (docs/liars.md). Pure; on floats."""

from __future__ import annotations

import math

import numpy as np

from vehicle.trust.neighbour_fixes import effective_count
from vehicle.trust.neighbours import MonitorSpec, NeighbourBook


def disagreement(book: NeighbourBook, spec: MonitorSpec, offset_m: np.ndarray, now_us: int) -> float:
    """How strongly the believed neighbours' recent fixes speak against moving the vehicle by
    ``offset_m`` (2,): the likelihood ratio of the fixes at the moved position against the present
    one, sum |w - G d|^2 - sum |w|^2 over the fixes of the last ``window_s`` that the gate passed
    (chi-square with 2 degrees of freedom when the move is as right as staying), counted with at most
    one fix per ``decorrelation_s`` per neighbour, as in the bias test. Neighbours that claim to be
    unsure say little: their G is small."""
    d0, d1 = float(offset_m[0]), float(offset_m[1])
    since, total = now_us - round(spec.window_s * 1e6), 0.0
    for record in book.records.values():
        if not record.believed:
            continue
        fixes = [f for f in record.fixes if f.stamp_us > since and not f.gated_out and math.isfinite(sum(f.whitened))]
        if not fixes:
            continue
        change = 0.0
        for f in fixes:
            g00, g01, g10, g11 = f.shift
            m0, m1 = f.whitened[0] - (g00 * d0 + g01 * d1), f.whitened[1] - (g10 * d0 + g11 * d1)
            change += m0 * m0 + m1 * m1 - f.whitened[0] ** 2 - f.whitened[1] ** 2
        total += change * effective_count(fixes, spec.decorrelation_s) / len(fixes)
    return total
