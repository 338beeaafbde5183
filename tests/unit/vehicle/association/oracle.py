"""The joint test's batch form, the oracle the pair-by-pair one is checked against (both dimensions)."""

from __future__ import annotations

import numpy as np
import pytest

from vehicle.association.problem import Joint, Problem, pairs_of


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


def grown_as_batch(p: Problem, assignment: np.ndarray) -> Joint:
    """The joint test grown pair by pair over an assignment, checked at each pair against the batch
    form (to 1e-9); the grown test."""
    rows, cols = pairs_of(assignment)
    joint = Joint()
    for n, (i, j) in enumerate(zip(rows.tolist(), cols.tolist())):
        joint = joint.plus(p, i, j)
        partial = np.full_like(assignment, -1)
        partial[rows[: n + 1]] = cols[: n + 1]
        assert joint.nis == pytest.approx(batch_nis(p, partial), rel=1e-9)
    return joint
