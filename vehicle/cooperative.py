"""Cooperative localization from relative measurements (cooperative-localization paper, pure).

Vehicle i measures neighbour j: z = [range, bearing] with h = [|p_j - p_i|, atan2(dy, dx) - theta_i].
Neighbour j broadcasts its own estimate p_j with covariance P_j (the V2V packet {id, x_hat, P, t}),
which enters as extra measurement noise: R_eff = R + H_j P_j H_j^T. Estimates of vehicles that fuse
each other become correlated in unknown ways (data incest), so the update is a Covariance
Intersection (paper): P+^-1 = w P^-1 + (1 - w) H^T R_eff^-1 H, with w in (0, 1) chosen to minimise
det(P+), done as a Kalman update with P / w and R_eff / (1 - w). The result is consistent whatever
the correlation between the two estimates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bus.angles import wrap_angle
from vehicle.ekf import UpdateResult, gated_update

WEIGHTS = np.linspace(0.02, 0.98, 49)


@dataclass(frozen=True)
class CooperativeFix:
    """A ranging measurement paired with the neighbour's broadcast estimate at the same stamp."""

    vehicle_id: int
    stamp_us: int
    seq: int
    target_id: int
    range_m: float
    bearing_rad: float
    covariance: np.ndarray           # (2, 2) over [range m, bearing rad]
    neighbour_xy_m: np.ndarray       # (2,)
    neighbour_cov_m2: np.ndarray     # (2, 2)


def relative_model(x: np.ndarray, neighbour_xy_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted [range, bearing] (2,), H = dh/dx_i (2, n) and H_j = dh/dp_j (2, 2) for state x (n,)."""
    dx, dy = neighbour_xy_m - x[:2]
    r2 = max(dx * dx + dy * dy, 1e-6)
    r = np.sqrt(r2)
    H = np.zeros((2, len(x)))
    H[0, :2] = [-dx / r, -dy / r]
    H[1, :3] = [dy / r2, -dx / r2, -1.0]
    return np.array([r, wrap_angle(np.arctan2(dy, dx) - x[2])]), H, -H[:, :2]


def inverse2(S: np.ndarray) -> np.ndarray:
    """Inverse of a 2 x 2 matrix (no LAPACK call: this runs for every ranging measurement)."""
    a, b, c, d = S[0, 0], S[0, 1], S[1, 0], S[1, 1]
    return np.array([[d, -b], [-c, a]]) / (a * d - b * c)


def ci_weight(P: np.ndarray, H: np.ndarray, R: np.ndarray) -> float:
    """The w of WEIGHTS that minimises det(P+) = 1 / det(w P^-1 + (1 - w) H^T R^-1 H)."""
    return ci_weight_from(H @ P @ H.T, R, P.shape[0])


def ci_weight_from(M: np.ndarray, R: np.ndarray, n: int) -> float:
    """``ci_weight`` from M = H P H^T (2, 2) and the state dimension n. H^T R^-1 H has rank 2, so by the matrix determinant
    lemma, with C = R^-1 M: det(w P^-1 + (1 - w) H^T R^-1 H) =
    det(P^-1) w^(n-2) (w^2 + w (1 - w) tr C + (1 - w)^2 det C), a scalar function of w: no n x n
    determinant per candidate weight."""
    C = inverse2(R) @ M
    trace, det = C[0, 0] + C[1, 1], C[0, 0] * C[1, 1] - C[0, 1] * C[1, 0]
    w = WEIGHTS
    log_info = (n - 2) * np.log(w) + np.log(w * w + w * (1.0 - w) * trace + (1.0 - w) ** 2 * det)
    return float(w[int(np.argmax(log_info))])


def neighbour_measurement(x: np.ndarray, fix: CooperativeFix) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Innovation y (2,) of a ranging fix at state x (n,), H = dh/dx (2, n) and the effective noise
    R_eff = R + H_j P_j H_j^T (2, 2): the neighbour's broadcast covariance enters as measurement noise."""
    predicted, H, Hj = relative_model(x, fix.neighbour_xy_m)
    R = fix.covariance + Hj @ fix.neighbour_cov_m2 @ Hj.T
    return np.array([fix.range_m - predicted[0], wrap_angle(fix.bearing_rad - predicted[1])]), H, R


def cooperative_terms(x: np.ndarray, P: np.ndarray, fix: CooperativeFix) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]:
    """The pieces of a CI update that depend only on the pose block: innovation y (2,), H on
    [x, y, theta] (2, 3), R_eff (2, 2), M = H P H^T (2, 2) and the plain NIS."""
    y, H, R = neighbour_measurement(x[:3], fix)
    M = H @ P[:3, :3] @ H.T
    return y, H, R, M, float(y @ inverse2(M + R) @ y)


def naive_update(x: np.ndarray, P: np.ndarray, fix: CooperativeFix,
                 gate: float) -> tuple[np.ndarray, np.ndarray, UpdateResult]:
    """A plain Kalman update (Joseph form) with R_eff = R + H_j P_j H_j^T: right only if the
    neighbour's estimate is independent of ours, which it stops being once they fuse each other
    (data incest): kept to show what double counting does."""
    y, H, R = neighbour_measurement(x, fix)
    x_new, P_new, result = gated_update(x, P, y, H, R, gate)
    if result.accepted:
        x_new[2] = wrap_angle(x_new[2])
    return x_new, P_new, result


def cooperative_update(x: np.ndarray, P: np.ndarray, fix: CooperativeFix,
                       gate: float) -> tuple[np.ndarray, np.ndarray, UpdateResult]:
    """CI update of (x (n,), P (n, n)) with one relative measurement; gated on the plain NIS."""
    y, H, R = neighbour_measurement(x, fix)
    HP = H @ P
    M = HP @ H.T
    nis = float(y @ inverse2(M + R) @ y)
    if not nis / gate <= 1.0:
        return x, P, UpdateResult(False, nis, nis / gate)
    w = ci_weight_from(M, R, len(x))
    Pw, Rw = P / w, R / (1.0 - w)
    K = (HP.T / w) @ inverse2(M / w + Rw)   # P_w H^T (H P_w H^T + R_w)^-1
    I_KH = np.eye(len(x)) - K @ H
    P_new = I_KH @ Pw @ I_KH.T + K @ Rw @ K.T  # Joseph form
    x_new = x + K @ y
    x_new[2] = wrap_angle(x_new[2])
    return x_new, 0.5 * (P_new + P_new.T), UpdateResult(True, nis, nis / gate)


def cooperative_update_in_place(x: np.ndarray, P: np.ndarray, fix: CooperativeFix, gate: float,
                                update_in_place) -> UpdateResult:
    """The same CI update on a large state (a SLAM map) without n x n temporaries: P <- P / w in
    place, then a Kalman update with R_eff / (1 - w) by ``update_in_place(x, P, idx, H, y, R, gate)``."""
    y, H, R, M, nis = cooperative_terms(x, P, fix)
    if not nis / gate <= 1.0:
        return UpdateResult(False, nis, nis / gate)
    w = ci_weight_from(M, R, len(x))
    P *= 1.0 / w
    update_in_place(x, P, [0, 1, 2], H, y, R / (1.0 - w), float("inf"))
    return UpdateResult(True, nis, nis / gate)
