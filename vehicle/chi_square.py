"""Chi-square quantiles for the vehicle's gates, without scipy (importing ``scipy.special`` cost every
vehicle process about 0.25 s of CPU at start, for a handful of numbers).

The survival function of chi-square with k degrees of freedom has a closed form built up two degrees
at a time, Q_{k+2}(x) = Q_k(x) + (x / 2)^(k / 2) exp(-x / 2) / Gamma(k / 2 + 1), from Q_2(x) = exp(-x / 2)
and Q_1(x) = erfc(sqrt(x / 2)) (Abramowitz and Stegun 26.4.4-5); the quantile follows by bisection to
the last bits of a float. Meant for the gates' few degrees of freedom (at most MAX_DOF). Pure.
"""

from __future__ import annotations

import math
from functools import cache

MAX_ITERATIONS = 200
MAX_DOF = 200


def survival(dof: int, x: float) -> float:
    """P(chi-square with ``dof`` (1..MAX_DOF) degrees of freedom > ``x``)."""
    _check_dof(dof)
    if x <= 0.0:
        return 1.0
    half = 0.5 * x
    if dof % 2:  # Q_1, and t_1 = (x/2)^(1/2) exp(-x/2) / Gamma(3/2)
        k, total, term = 1, math.erfc(math.sqrt(half)), math.sqrt(half) * math.exp(-half) / math.gamma(1.5)
    else:        # Q_2, and t_2 = (x/2) exp(-x/2) / Gamma(2)
        k, total, term = 2, math.exp(-half), half * math.exp(-half)
    while k < dof:  # Q_{k+2} = Q_k + t_k, t_{k+2} = t_k (x/2) / (k/2 + 1)
        total += term
        term *= half / (0.5 * k + 1.0)
        k += 2
    return total


@cache
def upper_quantile(dof: int, tail: float) -> float:
    """x with P(chi-square with ``dof`` degrees of freedom > x) = ``tail`` (0 < tail < 1): scipy's
    ``chdtri(dof, tail)``, ``chi2.isf(tail, dof)``."""
    _check_dof(dof)
    if not 0.0 < tail < 1.0:
        raise ValueError(f"tail probability {tail!r} is not inside (0, 1)")
    low, high = 0.0, float(dof)
    while survival(dof, high) > tail:  # the survival function falls: bracket the quantile
        low, high = high, 2.0 * high
    for _ in range(MAX_ITERATIONS):
        middle = 0.5 * (low + high)
        if middle in (low, high):
            break
        low, high = (middle, high) if survival(dof, middle) > tail else (low, middle)
    return 0.5 * (low + high)


def _check_dof(dof: int) -> None:
    if not 1 <= dof <= MAX_DOF:
        raise ValueError(f"{dof} degrees of freedom: expected 1 to {MAX_DOF}")
