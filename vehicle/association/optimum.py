"""The optimum of the gated linear assignment problem (``problem.linear_cost``), by the Hungarian
method of scipy: the yardstick the heuristics are measured against."""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from vehicle.association.problem import UNPAIRED, Problem, unpaired_cost


def optimal_assignment(p: Problem) -> np.ndarray:
    """The assignment (k,) of least linear cost: k x (m + k) costs, the k extra columns the price of
    leaving each observation unpaired (its own column only), non-candidates forbidden."""
    k, m = p.shape
    assignment = np.full(k, UNPAIRED, dtype=np.int64)
    if not k:
        return assignment
    big = 1e12
    leave = np.full((k, k), big)
    np.fill_diagonal(leave, unpaired_cost(p))
    costs = np.hstack([np.where(p.candidates, p.cost, big), leave])
    rows, cols = linear_sum_assignment(costs)
    paired = cols < m
    assignment[rows[paired]] = cols[paired]
    return assignment
