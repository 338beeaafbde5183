"""Whether a covariance is symmetric positive definite (SPD): the one place this is decided, for every
process. One definition, a Cholesky factorisation that succeeds on a finite symmetric matrix, written
the ways its callers' sizes and rates need, each checked against the others (tests/unit/bus/test_spd.py):

- ``spd``: any matrix (n, n): the plain-float forms below up to 4 x 4, numpy's Cholesky beyond;
- ``spd_values``: a small row-major matrix as floats (a decoded message's field), in plain Python;
- ``spd4``: 4 x 4 unrolled (a vehicle filter's pose block, every loop cycle);
- ``spd2_row`` and ``all_spd2``: 2 x 2 row-major rows, one or (k, 4) at once (a sensor batch's fixes
  and sightings); ``all_spd3``: (k, 9) rows by Sylvester's criterion (the launch priors).

A symmetric 2 x 2 [[a, b], [c, d]] is SPD when b = c (to 1e-9 relative), a > 0 and ad - bc > 0.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

SYMMETRY_RTOL = 1e-9


def spd_values(values: Sequence[float], n: int) -> bool:
    """Cholesky of a row-major symmetric ``n`` x ``n`` matrix in plain Python; True if it succeeds
    (every pivot finite and positive)."""
    low = [[0.0] * n for _ in range(n)]
    for i in range(n):
        for j in range(i + 1):
            s = values[i * n + j] - sum(low[i][k] * low[j][k] for k in range(j))
            if i == j:
                if not (s > 0.0 and math.isfinite(s)):
                    return False
                low[i][i] = math.sqrt(s)
            else:
                low[i][j] = s / low[j][j]
    return True


def spd4(P: np.ndarray) -> bool:
    """True when the symmetric 4 x 4 matrix P is finite and positive definite (Cholesky, unrolled:
    numpy's per-call cost dominates at this size, and a filter asks every cycle)."""
    rows = P.tolist()
    if not math.isfinite(sum(map(sum, rows))):
        return False
    (a00, a01, a02, a03), (_, a11, a12, a13), (_, _, a22, a23), (_, _, _, a33) = rows
    if not a00 > 0.0:
        return False
    l00 = math.sqrt(a00)
    l10, l20, l30 = a01 / l00, a02 / l00, a03 / l00
    d = a11 - l10 * l10
    if not d > 0.0:
        return False
    l11 = math.sqrt(d)
    l21, l31 = (a12 - l20 * l10) / l11, (a13 - l30 * l10) / l11
    d = a22 - l20 * l20 - l21 * l21
    if not d > 0.0:
        return False
    l32 = (a23 - l30 * l20 - l31 * l21) / math.sqrt(d)
    return a33 - l30 * l30 - l31 * l31 - l32 * l32 > 0.0


def spd(P: np.ndarray) -> bool:
    """True when the symmetric matrix P (n, n) is finite and positive definite."""
    n = P.shape[0]
    if n == 4:
        return spd4(P)
    if n < 4:
        return spd_values(P.ravel().tolist(), n)
    try:
        np.linalg.cholesky(P)
    except np.linalg.LinAlgError:
        return False
    return bool(np.isfinite(P).all())


def spd2_row(a: float, b: float, c: float, d: float) -> bool:
    """One row-major 2 x 2 matrix [[a, b], [c, d]] (module docstring), on floats."""
    return abs(b - c) <= SYMMETRY_RTOL * max(abs(b), 1e-300) and a > 0 and a * d - b * c > 0


def all_spd2(rows: np.ndarray) -> bool:
    """All rows (k, 4) are SPD 2 x 2 matrices (row-major), with :func:`spd2_row`'s operations."""
    a, b, c, d = rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3]
    symmetric = np.abs(b - c) <= SYMMETRY_RTOL * np.maximum(np.abs(b), 1e-300)
    return bool(symmetric.all() and (a > 0).all() and (a * d - b * c > 0).all())


def all_spd3(rows: np.ndarray) -> bool:
    """All rows (k, 9) are SPD 3 x 3 matrices (row-major; Sylvester's criterion: every leading minor
    positive)."""
    M = rows.reshape(-1, 3, 3)
    if not np.allclose(M, np.transpose(M, (0, 2, 1)), rtol=SYMMETRY_RTOL, atol=0.0):
        return False
    return bool((M[:, 0, 0] > 0).all() and (np.linalg.det(M[:, :2, :2]) > 0).all() and (np.linalg.det(M) > 0).all())
