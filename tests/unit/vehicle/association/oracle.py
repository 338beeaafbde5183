"""The joint test's batch form, the oracle the pair-by-pair one is checked against (both dimensions)."""

from __future__ import annotations

import numpy as np

from vehicle.association.problem import Problem, pairs_of


def batch_nis(p: Problem, assignment: np.ndarray) -> float:
    """The stacked innovation of the paired entries against C restricted to their landmarks plus the
    block-diagonal noise, solved at once."""
    d = p.dim
    rows, cols = pairs_of(assignment)
    idx = (d * cols[:, None] + np.arange(d)).ravel()
    S = p.C[np.ix_(idx, idx)].copy()
    for a, i in enumerate(rows):
        S[d * a : d * a + d, d * a : d * a + d] += p.R[i]
    y = p.y[rows, cols].ravel()
    return float(y @ np.linalg.solve(S, y))
