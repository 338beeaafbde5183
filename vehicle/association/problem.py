"""One frame's association problem: k observations z_i = [range m, bearing rad] with noise R_i, m
candidate landmarks with predicted observations h_j and the joint covariance of their predictions
C = H P H^T (2m, 2m) (H the observation Jacobians of all m landmarks stacked; the pose error they
share is what makes their innovations correlated). Individual compatibility (IC): pair (i, j) is a
candidate when its Mahalanobis distance d2_ij = y_ij^T S_ij^-1 y_ij (y_ij = z_i - h_j, S_ij = C_jj +
R_i) passes the chi-square gate and the front end allows it (``allowed``, e.g. a descriptor
shortlist). Its cost is the AR-EKF-SLAM paper's normalised distance d2_ij + ln|S_ij|.

An assignment is an array a (k,) of landmark indices, -1 for an observation left unpaired (a new
landmark or clutter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from scipy.linalg import solve_triangular

from bus.statistics import gate_threshold

UNPAIRED = -1


@dataclass(frozen=True)
class Problem:
    """The gated association problem of one frame (module docstring); read-only arrays."""

    y: np.ndarray  # (k, m, 2) innovations, bearings wrapped
    C: np.ndarray  # (2m, 2m) joint covariance of the predictions
    R: np.ndarray  # (k, 2, 2) observation noise
    d2: np.ndarray  # (k, m) Mahalanobis distances
    cost: np.ndarray  # (k, m) d2 + ln|S|, inf where not a candidate
    gate_probability: float

    @property
    def shape(self) -> tuple[int, int]:
        return self.d2.shape

    @property
    def candidates(self) -> np.ndarray:
        """(k, m) bool: the individually compatible pairs."""
        return np.isfinite(self.cost)


def problem(
    z: np.ndarray,
    R: np.ndarray,
    predicted: np.ndarray,
    C: np.ndarray,
    *,
    allowed: np.ndarray | None = None,
    gate_probability: float = 0.99,
) -> Problem:
    """The problem of observations z (k, 2) with noise R (k, 2, 2) against predictions (m, 2) of joint
    covariance C (2m, 2m); ``allowed`` (k, m) bool restricts the candidates (default: all)."""
    k, m = len(z), len(predicted)
    y = z[:, None, :] - predicted[None, :, :]
    y[..., 1] = (y[..., 1] + np.pi) % (2 * np.pi) - np.pi
    blocks = np.stack([C[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] for j in range(m)]) if m else np.zeros((0, 2, 2))
    S = blocks[None, :, :, :] + R[:, None, :, :]  # (k, m, 2, 2)
    d2 = np.einsum("kma,kmab,kmb->km", y, np.linalg.inv(S), y) if k and m else np.zeros((k, m))
    logdet = np.linalg.slogdet(S)[1] if k and m else np.zeros((k, m))
    ok = d2 <= gate_threshold(2, gate_probability)
    if allowed is not None:
        ok &= allowed
    cost = np.where(ok, d2 + logdet, np.inf)
    return Problem(y, C, R, d2, cost, gate_probability)


def pairs_of(assignment: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(observations, landmarks) of the paired entries of an assignment (k,)."""
    rows = np.flatnonzero(assignment >= 0)
    return rows, assignment[rows]


@dataclass(frozen=True)
class Joint:
    """A partial assignment's joint test, grown one pair at a time in O(p^2): the paired
    (observation, landmark)s, the rows of C they use (2p,), the lower Cholesky factor L (2p, 2p) of
    their joint innovation covariance S, the whitened stacked innovation w = L^-1 y (2p,) and the
    joint Mahalanobis distance |w|^2. The factor grows by a block row (c = L^-1 b, M = chol(D - c^T c)),
    which stays accurate where the innovations are strongly correlated (a shared pose error much
    larger than the noise) and an inverse grown by its Schur complement loses every digit."""

    pairs: tuple[tuple[int, int], ...] = ()
    rows: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    L: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    w: np.ndarray = field(default_factory=lambda: np.zeros(0))
    nis: float = 0.0

    def plus(self, p: Problem, i: int, j: int) -> Joint:
        """This test with pair (i, j) added (Neira and Tardos 2001: the joint distance updated)."""
        b = p.C[self.rows, 2 * j : 2 * j + 2]  # (2p, 2) cross-covariance with the new pair
        c = solve_triangular(self.L, b, lower=True) if len(self.w) else np.zeros((0, 2))
        M = _chol2(p.C[2 * j : 2 * j + 2, 2 * j : 2 * j + 2] + p.R[i] - c.T @ c)
        w_new = _solve_lower2(M, p.y[i, j] - c.T @ self.w)
        n = len(self.w)
        L = np.zeros((n + 2, n + 2))
        L[:n, :n] = self.L
        L[n:, :n] = c.T
        L[n:, n:] = M
        rows = np.concatenate([self.rows, [2 * j, 2 * j + 1]])
        return Joint((*self.pairs, (i, j)), rows, L, np.concatenate([self.w, w_new]), self.nis + float(w_new @ w_new))

    def compatible(self, p: Problem) -> bool:
        """Whether the pairs pass the joint chi-square gate of their dimension."""
        return not self.pairs or self.nis <= _joint_gate(2 * len(self.pairs), p.gate_probability)


def _chol2(A: np.ndarray) -> np.ndarray:
    """The lower Cholesky factor of a 2 x 2 covariance (floored: a rounding error is not certainty)."""
    a = math.sqrt(max(A[0, 0], 1e-18))
    b = A[1, 0] / a
    return np.array([[a, 0.0], [b, math.sqrt(max(A[1, 1] - b * b, 1e-18))]])


def _solve_lower2(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    first = v[0] / M[0, 0]
    return np.array([first, (v[1] - M[1, 0] * first) / M[1, 1]])


@lru_cache(maxsize=256)
def _joint_gate(dof: int, probability: float) -> float:
    return gate_threshold(dof, probability)


def joint_of(p: Problem, assignment: np.ndarray) -> Joint:
    """The joint test of all pairs of an assignment."""
    joint = Joint()
    for i, j in zip(*pairs_of(assignment)):
        joint = joint.plus(p, int(i), int(j))
    return joint


def joint_nis(p: Problem, assignment: np.ndarray) -> float:
    """The joint Mahalanobis distance of all pairs of an assignment (Neira and Tardos 2001): the
    stacked innovation against C restricted to the paired landmarks plus the block-diagonal noise."""
    return joint_of(p, assignment).nis


def jointly_compatible(p: Problem, assignment: np.ndarray) -> bool:
    """Whether the pairs of an assignment pass the joint chi-square gate of their dimension."""
    return joint_of(p, assignment).compatible(p)


def linear_cost(p: Problem, assignment: np.ndarray) -> float:
    """The assignment's cost in the linear problem the optimum solves: each pair's cost, and for each
    observation left unpaired the price of leaving it (``unpaired_cost``)."""
    rows, cols = pairs_of(assignment)
    unpaired = np.flatnonzero(assignment < 0)
    return float(p.cost[rows, cols].sum() + unpaired_cost(p)[unpaired].sum())


def unpaired_cost(p: Problem) -> np.ndarray:
    """(k,) the price of leaving observation i unpaired: above every candidate pair it has (the gate
    plus its largest ln|S|), so the optimum pairs all it can and then prefers the cheaper pairs."""
    finite = np.where(p.candidates, p.cost - p.d2, -np.inf)
    largest = finite.max(axis=1, initial=-np.inf) if p.shape[1] else np.full(p.shape[0], -np.inf)
    gate = gate_threshold(2, p.gate_probability)
    return gate + np.where(np.isfinite(largest), largest, 0.0) + 1.0
