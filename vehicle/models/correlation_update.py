"""One exact one-sided fusion of a neighbour's broadcast with the cross-covariance its factors give
(vehicle.models.correlation, equation 2 there), and the checks a claim must pass before its
correlation is used. Pure."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.models.correlation import POSE


@dataclass(frozen=True)
class PairUpdate:
    """One exact one-sided fusion: the new mean (n,) and covariance (n, n), the gain K (n, m), the
    fuser's new factor (n, 3) (equation 2), the NIS and the innovation covariance S (m, m)."""

    x: np.ndarray
    P: np.ndarray
    K: np.ndarray
    factor: np.ndarray
    nis: float
    S: np.ndarray


def pair_update(
    x: np.ndarray,
    P: np.ndarray,
    y: np.ndarray,
    H_own: np.ndarray,
    H_their: np.ndarray,
    R: np.ndarray,
    C: np.ndarray,
    U: np.ndarray,
) -> PairUpdate:
    """The fuser's exact update (module docstring): state x (n,), P (n, n), innovation y (m,), Jacobians
    H_own (m, n) and H_their (m, 3) on the neighbour's broadcast pose, noise R (m, m) independent of
    both, C = cov(e, e_their) (n, 3), U = cov(e_their) (3, 3)."""
    PHt = P @ H_own.T + C @ H_their.T  # cov(e, z error)
    HC = H_own @ C
    S = H_own @ PHt + H_their @ (HC.T + U @ H_their.T) + R
    S = 0.5 * (S + S.T)
    S_inv = np.linalg.inv(S)
    K = PHt @ S_inv
    P_new = P - K @ S @ K.T
    factor = C - K @ (HC + H_their @ U)
    return PairUpdate(x + K @ y, 0.5 * (P_new + P_new.T), K, factor, float(y @ S_inv @ y), S)


def joint_is_positive(P: np.ndarray, C: np.ndarray, U: np.ndarray) -> bool:
    """Whether the joint covariance [[P, C], [C^T, U]] is positive definite (a claim that makes it
    indefinite says a correlation no two estimates can have)."""
    try:
        np.linalg.cholesky(np.block([[P, C], [C.T, U]]))
    except np.linalg.LinAlgError:
        return False
    return True


def shrinks_at_most_as_independent(
    P: np.ndarray, H_own: np.ndarray, H_their: np.ndarray, R: np.ndarray, C: np.ndarray, U: np.ndarray
) -> bool:
    """Whether the exact update leaves the pose covariance no smaller, in any direction, than an update
    that took the neighbour's estimate as independent of this one: the bound on how much one neighbour's
    claim may shrink it. (The correlation that fusing each other builds is positive along what a relative
    measurement sees: the pair's relative pose is better known than their poses, so an honest claim
    brings less than independence would.)"""
    exact = pair_update(np.zeros(len(P)), P, np.zeros(len(R)), H_own, H_their, R, C, U).P[:POSE, :POSE]
    independent = pair_update(np.zeros(len(P)), P, np.zeros(len(R)), H_own, H_their, R, 0.0 * C, U).P[:POSE, :POSE]
    L = np.linalg.cholesky(independent)
    ratio = np.linalg.solve(L, np.linalg.solve(L, exact).T)
    return bool(np.linalg.eigvalsh(0.5 * (ratio + ratio.T)).min() >= 1.0 - 1e-6)
