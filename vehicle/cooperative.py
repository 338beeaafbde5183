"""Cooperative localization from relative measurements (cooperative-localization paper, pure).

Vehicle i measures neighbour j: z = [range, bearing] with h = [|p_j - p_i|, atan2(dy, dx) - theta_i].
Neighbour j broadcasts its own estimate p_j with covariance P_j (the V2V packet {id, x_hat, P, t}),
which enters as extra measurement noise S = H_j P_j H_j^T next to the radio's own noise R. Estimates of
vehicles that fuse each other become correlated in unknown ways (data incest), so the update is a
Covariance Intersection (paper eq. 4.10: P+^-1 = w P^-1 + (1 - w) P_B^-1), done as a Kalman update
with the prior P / w and the measurement's shared part scaled by 1 / (1 - w). How it is done
(``CooperativeRule``):

- ``fusion``: ``split-ci`` (default) scales only the neighbour's part S: the radio's noise R is
  independent of both estimates and stays whole (split CI, Julier & Uhlmann 2001); ``ci`` scales
  R + S (plain CI); ``paper`` fuses the position the fix implies, p_B = p_j - r [cos, sin](theta_i +
  beta), with P_B = P_j + J R J^T + (heading term), by plain CI on [x, y] (eqs. 4.10-4.11); ``naive``
  is a plain Kalman update with R + S, right only for independent estimates (kept to show what
  double counting does).
- ``weight``: ``optimal`` takes w in [0, 1] maximising det of the fused information about the
  measured quantity (w = 1: the fix brings nothing, do not fuse); ``closed-form`` is the exact maximum
  of plain CI's determinant, a quadratic in w for 2 x 2 blocks (no search), used for every fusion.

The intersection is made in the measurement space, on z = h(pose), the only part of the state the fix
observes: own M = cov(h(pose)) against the fix's noise, giving a fused z+ with covariance M+. The
whole state then follows z through its regression on it, x += A (z+ - z_hat), P += A (M+ - M) A^T
with A = cov(x, z) M^-1: for w = 1 and no scaling this is exactly the Kalman update, and nothing
outside the two measured directions is inflated by 1 / w (plain CI on the full state inflates
heading, gyro bias and a whole SLAM map at every fix; Luft et al., IJRR 2018, update the rest of the
state the same way).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Literal

import numpy as np
from scipy.linalg.blas import dger

from bus.angles import wrap_angle
from vehicle import unscented as ut
from vehicle.ekf import UpdateResult

POSE = 3
WEIGHT_GRID = np.linspace(0.0, 1.0, 101)   # w = 0: only the fix; w = 1: do not fuse
Fusion = Literal["split-ci", "ci", "paper", "naive"]
Weight = Literal["optimal", "closed-form"]


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


@dataclass(frozen=True)
class Correction:
    """A fused fix in measurement space: dz (2,) = z+ - z_hat, M (2, 2) before and M+ (2, 2) after,
    C (3, 2) = cov(pose, z), and the weight w."""

    dz: np.ndarray
    M: np.ndarray
    M_new: np.ndarray
    C: np.ndarray
    w: float


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
    """Inverses of 2 x 2 matrices (..., 2, 2) in closed form (no LAPACK call: this runs for every
    ranging measurement)."""
    adjugate = np.stack([S[..., 1, 1], -S[..., 0, 1], -S[..., 1, 0], S[..., 0, 0]], axis=-1).reshape(S.shape)
    return adjugate / _det2(S)[..., None, None]


def _det2(A: np.ndarray) -> np.ndarray:
    """Determinants of 2 x 2 matrices (..., 2, 2)."""
    return A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]


def neighbour_measurement(x: np.ndarray, fix: CooperativeFix) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Range-bearing innovation y (2,) at pose x (3+,), H = dh/dx_pose (2, 3), the radio's noise R
    (2, 2) and the neighbour's share S = H_j P_j H_j^T (2, 2)."""
    predicted, H, Hj = relative_model(x[:POSE], fix.neighbour_xy_m)
    y = np.array([fix.range_m - predicted[0], wrap_angle(fix.bearing_rad - predicted[1])])
    return y, H, fix.covariance, Hj @ fix.neighbour_cov_m2 @ Hj.T


def implied_position(x: np.ndarray, P_pp: np.ndarray, fix: CooperativeFix) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The paper's form: innovation p_B - p_i (2,) where p_B is the position the fix implies, H = [I 0]
    (2, 3), R = 0 and P_B (2, 2) = P_j + J R J^T + g P_thth g^T (J = d p_B / d[r, beta], g = d p_B /
    d theta), all of it to be scaled by CI (p_B shares our heading's error: CI allows for that)."""
    angle = x[2] + fix.bearing_rad
    c, s = np.cos(angle), np.sin(angle)
    p_b = fix.neighbour_xy_m - fix.range_m * np.array([c, s])
    J = -np.array([[c, -fix.range_m * s], [s, fix.range_m * c]])
    g = fix.range_m * np.array([s, -c])
    P_b = fix.neighbour_cov_m2 + J @ fix.covariance @ J.T + P_pp[2, 2] * np.outer(g, g)
    return p_b - x[:2], np.eye(2, POSE), np.zeros((2, 2)), P_b


@dataclass(frozen=True)
class CooperativeRule:
    """How a vehicle fuses a neighbour fix: see the module docstring."""

    fusion: Fusion = "split-ci"
    weight: Weight = "optimal"

    def fix_information(self, R: np.ndarray, S: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Information (k, 2, 2) the fix brings at weights w (k,): split CI (1 - w) ((1 - w) R + S)^-1
        = (R + S / (1 - w))^-1, plain CI (1 - w) (R + S)^-1, naive (R + S)^-1."""
        w = np.asarray(w, dtype=float)[:, None, None]
        if self.fusion == "naive":
            return np.broadcast_to(inverse2(R + S), w.shape[:1] + (2, 2))
        if self.fusion == "split-ci":
            return (1.0 - w) * inverse2((1.0 - w) * R + S)
        return (1.0 - w) * inverse2(R + S)[None]

    def choose_weight(self, M: np.ndarray, R: np.ndarray, S: np.ndarray) -> float:
        """w in [0, 1] for own covariance M (2, 2) of the measured quantity and the fix's noise R, S."""
        if self.fusion == "naive":
            return 1.0
        if self.weight == "closed-form":
            return closed_form_weight(M, R + S)
        w = WEIGHT_GRID  # det(w M^-1 + fix information), the fused information about z (eq. 4.10)
        fused = w[:, None, None] * inverse2(M)[None] + self.fix_information(R, S, w)
        return float(w[int(np.argmax(_det2(fused)))])

    def fuse(self, x: np.ndarray, P: np.ndarray, fix: CooperativeFix, gate: float, unscented: bool = False,
             adapt: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None = None
             ) -> tuple[Correction | None, UpdateResult]:
        """Gate the fix on its plain NIS, choose w and fuse it in measurement space; None when gated
        out or when w = 1. ``unscented``: range and bearing through sigma points of the pose marginal
        (paper eqs. 4.1-4.9) instead of the linearization. ``adapt(y, M + S, R)``: the radio noise to
        use instead of R (IAE, vehicle.adaptive)."""
        y, M, C, R, S = self.measurement(x, P[:POSE, :POSE], fix, unscented)
        if adapt is not None:
            R = adapt(y, M + S, R)
        nis = float(y @ inverse2(M + R + S) @ y)
        result = UpdateResult(bool(nis <= gate), nis, nis / gate)
        if not result.accepted:
            return None, result
        w = self.choose_weight(M, R, S)
        if w >= 1.0 and self.fusion != "naive":
            return None, result
        fix_info = self.fix_information(R, S, np.array([w]))[0]
        own_info = w * inverse2(M) if w > 0.0 else np.zeros((2, 2))
        M_new = inverse2(own_info + fix_info)
        return Correction(M_new @ fix_info @ y, M, 0.5 * (M_new + M_new.T), C, w), result

    def measurement(self, x: np.ndarray, P_pp: np.ndarray, fix: CooperativeFix,
                     unscented: bool) -> tuple[np.ndarray, ...]:
        """Innovation y (2,), own covariance of the measured quantity M (2, 2), the cross-covariance
        C = cov(pose, z) (3, 2), the independent noise R and the neighbour's share S (2, 2 each)."""
        if self.fusion == "paper":
            y, H, R, S = implied_position(x, P_pp, fix)
        elif unscented:
            def h(pose: np.ndarray) -> np.ndarray:
                return relative_model(pose, fix.neighbour_xy_m)[0]

            z_hat, M, C = ut.measure(x[:POSE], P_pp, h, angle_rows=(1,))
            _, _, R, S = neighbour_measurement(x, fix)
            return np.array([fix.range_m - z_hat[0], wrap_angle(fix.bearing_rad - z_hat[1])]), M, C, R, S
        else:
            y, H, R, S = neighbour_measurement(x, fix)
        C = P_pp @ H.T
        return y, H @ C, C, R, S


def closed_form_weight(M: np.ndarray, R: np.ndarray) -> float:
    """The w in [0, 1] maximising det(w M^-1 + (1 - w) R^-1) (plain CI of two 2 x 2 estimates) in
    closed form: with A = M^-1, B = R^-1, D = A - B it is the quadratic det(B) + w tr(adj(B) D) +
    w^2 det(D), so the best w is an end point or the vertex."""
    A, B = inverse2(M), inverse2(R)
    D = A - B
    linear = B[1, 1] * D[0, 0] + B[0, 0] * D[1, 1] - B[0, 1] * D[1, 0] - B[1, 0] * D[0, 1]  # tr(adj(B) D)
    quadratic = float(_det2(D))
    candidates = [0.0, 1.0]
    if quadratic < 0.0:
        candidates.append(float(np.clip(-linear / (2.0 * quadratic), 0.0, 1.0)))
    return max(candidates, key=lambda w: linear * w + quadratic * w * w)


def regression_on_z(P: np.ndarray, correction: Correction) -> np.ndarray:
    """A = cov(x, z) M^-1 (n, 2), with cov(x, z) = P_{.p} P_pp^-1 C: how every state follows z."""
    return np.linalg.solve(P[:POSE, :POSE], P[:POSE, :]).T @ correction.C @ inverse2(correction.M)


def apply_correction(x: np.ndarray, P: np.ndarray, correction: Correction) -> tuple[np.ndarray, np.ndarray]:
    """The full state (n,) and covariance (n, n) after a fused fix (module docstring)."""
    A = regression_on_z(P, correction)
    x_new = x + A @ correction.dz
    x_new[2] = wrap_angle(x_new[2])
    P_new = P + A @ (correction.M_new - correction.M) @ A.T
    return x_new, 0.5 * (P_new + P_new.T)


def apply_correction_in_place(x: np.ndarray, P: np.ndarray, correction: Correction) -> None:
    """``apply_correction`` on a large state (a SLAM map, P C-contiguous) without n x n temporaries:
    the change of P is A D A^T with D = M+ - M (2, 2), applied as two rank-1 updates."""
    A = regression_on_z(P, correction)
    x += A @ correction.dz
    x[2] = wrap_angle(x[2])
    values, vectors = np.linalg.eigh(correction.M_new - correction.M)
    for value, u in zip(values, (A @ vectors).T):
        dger(float(value), u, u, a=P.T, overwrite_a=True)


def cooperative_update(x: np.ndarray, P: np.ndarray, fix: CooperativeFix, gate: float,
                       rule: CooperativeRule = CooperativeRule(), unscented: bool = False
                       ) -> tuple[np.ndarray, np.ndarray, UpdateResult]:
    """One fix fused into (x (n,), P (n, n)) by ``rule``: the new state and covariance (unchanged when
    gated out or not worth fusing) and the gate's result."""
    correction, result = rule.fuse(x, P, fix, gate, unscented)
    if correction is None:
        return x, P, result
    x_new, P_new = apply_correction(x, P, correction)
    return x_new, P_new, result
