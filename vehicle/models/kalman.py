"""The Kalman update every estimator shares: one gated update in Joseph form (gates from
``bus.statistics.gate_threshold``)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class UpdateResult:
    """Outcome of one measurement update; ``test_ratio`` = NIS / gate, accepted when <= 1; where the
    update says them (a neighbour's fix, for the neighbour monitor): the ``innovation`` y (m floats)
    and its covariance S as its upper triangle (``innovation_cov``, row by row)."""

    accepted: bool
    nis: float
    test_ratio: float
    innovation: tuple[float, ...] | None = None
    innovation_cov: tuple[float, ...] | None = None


def gated_update(
    x: np.ndarray,
    P: np.ndarray,
    innovation: np.ndarray,
    H: np.ndarray,
    R: np.ndarray,
    gate: float,
    *,
    columns: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, UpdateResult]:
    """One EKF update in Joseph form, skipped when the innovation fails the gate.

    x (n,), P (n, n), innovation y = z - h(x) (m,), H (m, n), R (m, m), gate = chi-square threshold.
    Returns the new x, P (symmetric positive definite) and the test result.
    P+ = (I - K H) P (I - K H)^T + K R K^T   (Joseph form, stable for any gain K).

    ``columns``: the states H depends on (H is zero elsewhere; a landmark sighting in a large map).
    Then the same Joseph form is taken expanded, P+ = P - K A^T - A K^T + K S K^T with A = P H^T,
    in O(n^2 m) instead of O(n^3) (the same function of K, so as stable; its rounding differs).
    """
    PHt = P @ H.T if columns is None else P[:, columns] @ H[:, columns].T
    S = H @ PHt + R
    S_inv = _inverse2(S) if S.shape == (2, 2) else np.linalg.inv(S)
    nis = float(innovation @ S_inv @ innovation)
    ratio = nis / gate
    if not ratio <= 1.0:  # also rejects NaN
        return x, P, UpdateResult(False, nis, ratio)
    K = PHt @ S_inv  # K = P H^T S^-1
    if columns is None:
        I_KH = np.eye(len(x)) - K @ H
        P_new = I_KH @ P @ I_KH.T + K @ R @ K.T
    else:
        P_new = P + K @ (S @ K.T - PHt.T) - PHt @ K.T
    return x + K @ innovation, 0.5 * (P_new + P_new.T), UpdateResult(True, nis, ratio)


def _inverse2(S: np.ndarray) -> np.ndarray:
    """The inverse of a 2 x 2 matrix on floats (LAPACK's per-call cost dominates at this size); a
    singular S raises ZeroDivisionError."""
    (a, b), (c, d) = S.tolist()
    det = a * d - b * c
    return np.array([[d / det, -b / det], [-c / det, a / det]])
