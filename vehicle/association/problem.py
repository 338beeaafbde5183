"""One frame's association problem: k observations z_i of d dimensions with noise R_i (in 2-D
[range m, bearing rad], the bearing an angle; in 3-D a triangulated point in the body frame [m]), m
candidate landmarks with predicted observations h_j and the joint covariance of their predictions
C = H P H^T (dm, dm) (H the observation Jacobians of all m landmarks stacked; the pose error they
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

    y: np.ndarray  # (k, m, d) innovations, angles wrapped
    C: np.ndarray  # (dm, dm) joint covariance of the predictions
    R: np.ndarray  # (k, d, d) observation noise
    d2: np.ndarray  # (k, m) Mahalanobis distances
    cost: np.ndarray  # (k, m) d2 + ln|S|, inf where not a candidate
    gate_probability: float

    @property
    def shape(self) -> tuple[int, int]:
        return self.d2.shape

    @property
    def dim(self) -> int:
        """d, the dimension of one observation."""
        return self.R.shape[-1]

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
    angles: tuple[int, ...] = (1,),
) -> Problem:
    """The problem of observations z (k, d) with noise R (k, d, d) against predictions (m, d) of joint
    covariance C (dm, dm); ``allowed`` (k, m) bool restricts the candidates (default: all); ``angles``:
    the components wrapped to [-pi, pi) (the bearing of a 2-D observation; none of a 3-D point)."""
    k, m, d = len(z), len(predicted), np.shape(z)[1]
    y = z[:, None, :] - predicted[None, :, :]
    for a in angles:
        y[..., a] = (y[..., a] + np.pi) % (2 * np.pi) - np.pi
    blocks = np.stack([C[d * j : d * j + d, d * j : d * j + d] for j in range(m)]) if m else np.zeros((0, d, d))
    S = blocks[None, :, :, :] + R[:, None, :, :]  # (k, m, d, d)
    d2 = np.einsum("kma,kmab,kmb->km", y, np.linalg.inv(S), y) if k and m else np.zeros((k, m))
    logdet = np.linalg.slogdet(S)[1] if k and m else np.zeros((k, m))
    ok = d2 <= gate_threshold(d, gate_probability)
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
    (observation, landmark)s, the rows of C they use (dp,), the lower Cholesky factor L (dp, dp) of
    their joint innovation covariance S, the whitened stacked innovation w = L^-1 y (dp,) and the
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
        d = p.dim
        b = p.C[self.rows, d * j : d * j + d]  # (dp, d) cross-covariance with the new pair
        c = solve_triangular(self.L, b, lower=True) if len(self.w) else np.zeros((0, d))
        M = _chol(p.C[d * j : d * j + d, d * j : d * j + d] + p.R[i] - c.T @ c)
        w_new = _solve_lower(M, p.y[i, j] - c.T @ self.w)
        n = len(self.w)
        L = np.zeros((n + d, n + d))
        L[:n, :n] = self.L
        L[n:, :n] = c.T
        L[n:, n:] = M
        rows = np.concatenate([self.rows, np.arange(d * j, d * j + d)])
        return Joint((*self.pairs, (i, j)), rows, L, np.concatenate([self.w, w_new]), self.nis + float(w_new @ w_new))

    def compatible(self, p: Problem) -> bool:
        """Whether the pairs pass the joint chi-square gate of their dimension."""
        return not self.pairs or self.nis <= _joint_gate(p.dim * len(self.pairs), p.gate_probability)


def _chol(A: np.ndarray) -> np.ndarray:
    """The lower Cholesky factor of a d x d covariance (floored: a rounding error is not certainty);
    2 x 2 on floats."""
    if A.shape == (2, 2):
        return _chol2(A)
    values, vectors = np.linalg.eigh(0.5 * (A + A.T))
    return np.linalg.cholesky((vectors * np.maximum(values, 1e-18)) @ vectors.T)


def _solve_lower(M: np.ndarray, v: np.ndarray) -> np.ndarray:
    return _solve_lower2(M, v) if M.shape == (2, 2) else solve_triangular(M, v, lower=True)


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
    gate = gate_threshold(p.dim, p.gate_probability)
    return gate + np.where(np.isfinite(largest), largest, 0.0) + 1.0
