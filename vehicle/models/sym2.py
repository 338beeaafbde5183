"""Symmetric 2 x 2 matrices on plain floats, as (a00, a01, a11): a neighbour fix's algebra
(vehicle.models.cooperative), where numpy's per-call cost would dominate 2 x 2 products. Pure."""

from __future__ import annotations

import numpy as np

Sym2 = tuple[float, float, float]  # a symmetric 2 x 2 matrix as (a00, a01, a11)


def sym(A: np.ndarray) -> Sym2:
    """(a00, a01, a11) of a symmetric 2 x 2 array."""
    (a, b), (_, d) = A.tolist()
    return a, b, d


def inv_sym(a: float, b: float, d: float) -> Sym2:
    """The inverse of the symmetric 2 x 2 (a, b, d) (ZeroDivisionError when singular)."""
    det = a * d - b * b
    return d / det, -b / det, a / det


def add_sym(*terms: Sym2) -> Sym2:
    """The sum of symmetric 2 x 2 matrices, entry by entry in ``sum``'s order (from 0.0)."""
    a = b = d = 0.0
    for t0, t1, t2 in terms:
        a, b, d = a + t0, b + t1, d + t2
    return a, b, d


def as_array(a: Sym2) -> np.ndarray:
    """The (2, 2) array of ``a``."""
    return np.array([[a[0], a[1]], [a[1], a[2]]])
