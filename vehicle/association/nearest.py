"""Mahalanobis nearest neighbour (AR-EKF-SLAM paper): among the individually compatible landmarks,
the one with the smallest normalised distance d2 + ln|S| (the paper's tie-break N_k). One landmark
per observation and one observation per landmark: pairs taken in increasing cost."""

from __future__ import annotations

import numpy as np

from vehicle.association.problem import UNPAIRED, Problem


def nearest_neighbour(p: Problem) -> np.ndarray:
    """The assignment (k,) (-1: unpaired)."""
    k, m = p.shape
    assignment = np.full(k, UNPAIRED, dtype=np.int64)
    if not k or not m:
        return assignment
    order = np.argsort(p.cost, axis=None, kind="stable")
    taken = np.zeros(m, dtype=bool)
    for flat in order.tolist():
        i, j = divmod(flat, m)
        if not np.isfinite(p.cost[i, j]):
            break
        if assignment[i] == UNPAIRED and not taken[j]:
            assignment[i], taken[j] = j, True
    return assignment
