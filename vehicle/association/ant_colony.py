"""The improved ant colony association of the AR-EKF-SLAM paper (after Geng and Chulin 2015): on the
individually compatible pairs (stage 1, ``problem``), ants build assignments (stage 2). Each ant
visits the observations in a random order and gives each a free candidate landmark that keeps its
assignment jointly compatible, or none, with probability proportional to tau^alpha eta^beta
(pheromone tau; heuristic eta = exp(-cost / 2), the pair's Gaussian likelihood, cost = d2 + ln|S|,
and for none the price of staying unpaired). Assignments rank by pairs, then least joint distance (as
JCBB). After each iteration the pheromone evaporates and the best assignment so far deposits on its
choices; the paper's improvements: a random perturbation of that global update (against early
convergence to a local optimum) and pheromone bounds [tau_min, tau_max] (as the MAX-MIN ant system,
Stuetzle and Hoos 2000). Seeded: an explicit ``np.random.Generator``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.association.problem import UNPAIRED, Joint, Problem, unpaired_cost


@dataclass(frozen=True)
class AcoSpec:
    ants: int = 6
    iterations: int = 8
    alpha: float = 1.0  # weight of the pheromone
    beta: float = 1.0  # weight of the heuristic
    evaporation: float = 0.3
    tau_min: float = 0.05
    tau_max: float = 1.0
    perturbation: float = 0.3  # each deposit is scaled by a uniform draw in [1 - p, 1 + p]


def ant_colony(p: Problem, rng: np.random.Generator, spec: AcoSpec = AcoSpec()) -> np.ndarray:
    """The assignment (k,) (-1: unpaired)."""
    k, m = p.shape
    rows = [i for i in range(k) if p.candidates[i].any()]
    assignment = np.full(k, UNPAIRED, dtype=np.int64)
    if not rows:
        return assignment
    eta = heuristic(p) ** spec.beta  # (k, m + 1), column m: stay unpaired
    tau = np.full((k, m + 1), spec.tau_max)
    best = Joint()
    for _ in range(spec.iterations):
        for _ in range(spec.ants):
            found = _walk(p, rows, tau**spec.alpha * eta, rng)
            if _better(found, best):
                best = found
        tau *= 1.0 - spec.evaporation
        chosen = np.full(k, m)
        for i, j in best.pairs:
            chosen[i] = j
        quality = 1.0 / (1.0 + best.nis / max(len(best.pairs), 1))
        tau[np.arange(k), chosen] += quality * rng.uniform(1 - spec.perturbation, 1 + spec.perturbation, k)
        np.clip(tau, spec.tau_min, spec.tau_max, out=tau)
    for i, j in best.pairs:
        assignment[i] = j
    return assignment


def heuristic(p: Problem) -> np.ndarray:
    """(k, m + 1): each pair's likelihood exp(-cost / 2), the last column staying unpaired's, each row
    scaled to a maximum of 1 (no underflow)."""
    costs = np.hstack([p.cost, unpaired_cost(p)[:, None]])
    return np.exp(-0.5 * (costs - costs.min(axis=1, keepdims=True)))


def _walk(p: Problem, rows: list[int], weights: np.ndarray, rng: np.random.Generator) -> Joint:
    """One ant: the observations in a random order, each a free landmark that keeps the assignment
    jointly compatible, or none."""
    m = p.shape[1]
    joint, used = Joint(), set()
    for i in rng.permutation(rows).tolist():
        options, grown = [m], [joint]
        for j in np.flatnonzero(p.candidates[i]).tolist():
            if j not in used:
                trial = joint.plus(p, i, j)
                if trial.compatible(p):
                    options.append(j)
                    grown.append(trial)
        w = weights[i, options]
        pick = int(rng.choice(len(options), p=w / w.sum()))
        if pick:
            joint = grown[pick]
            used.add(options[pick])
    return joint


def _better(a: Joint, b: Joint) -> bool:
    return len(a.pairs) > len(b.pairs) or (len(a.pairs) == len(b.pairs) and a.nis < b.nis)
