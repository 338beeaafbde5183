"""Joint compatibility branch and bound (Neira and Tardos, "Data association in stochastic mapping
using the joint compatibility test", IEEE T-RA 2001): of all assignments whose pairs are *jointly*
compatible (the stacked innovation, with the correlations the shared pose error gives it, passes the
chi-square gate of its dimension), the one with the most pairs, ties to the least joint distance. A
pose error moves every true pair alike; individually plausible pairs that disagree on it are refused.

Depth-first over the observations with candidates, the least ambiguous first and each one's cheapest
candidate first; the branch that leaves an observation unpaired is explored only while it can still
beat the best pair count. The joint test grows by one pair per node in O(p^2) (``problem.Joint``). A
node budget bounds the worst case (exponential): when spent, the best assignment so far is returned.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.association.problem import UNPAIRED, Joint, Problem

NODE_BUDGET = 3000


@dataclass
class _Search:
    p: Problem
    order: list[int]  # the observations with candidates, in search order
    options: dict[int, list[int]]  # observation -> its candidate landmarks, cheapest first
    budget: int
    best: Joint = Joint()
    nodes: int = 0


def jcbb(p: Problem, *, node_budget: int = NODE_BUDGET) -> np.ndarray:
    """The assignment (k,) (-1: unpaired)."""
    candidates = p.candidates
    order = sorted((i for i in range(p.shape[0]) if candidates[i].any()), key=lambda i: int(candidates[i].sum()))
    options = {i: sorted(np.flatnonzero(candidates[i]).tolist(), key=lambda j: p.cost[i, j]) for i in order}
    search = _Search(p, order, options, node_budget)
    _branch(search, Joint(), 0)
    assignment = np.full(p.shape[0], UNPAIRED, dtype=np.int64)
    for i, j in search.best.pairs:
        assignment[i] = j
    return assignment


def _better(a: Joint, b: Joint) -> bool:
    return len(a.pairs) > len(b.pairs) or (len(a.pairs) == len(b.pairs) and a.nis < b.nis)


def _branch(s: _Search, joint: Joint, depth: int) -> None:
    s.nodes += 1
    if depth == len(s.order):
        if _better(joint, s.best):
            s.best = joint
        return
    i = s.order[depth]
    used = {j for _, j in joint.pairs}
    for j in s.options[i]:
        if s.nodes >= s.budget:
            return
        if j not in used:
            grown = joint.plus(s.p, i, j)
            if grown.compatible(s.p):
                _branch(s, grown, depth + 1)
    if len(joint.pairs) + len(s.order) - depth - 1 > len(s.best.pairs) and s.nodes < s.budget:
        _branch(s, joint, depth + 1)
