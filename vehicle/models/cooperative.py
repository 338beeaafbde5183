"""Cooperative localization from relative measurements (cooperative-localization paper, pure).

Vehicle i measures neighbour j: z = [range, bearing] with h = [|p_j - p_i|, atan2(dy, dx) - theta_i].
Neighbour j broadcasts its own estimate p_j with covariance P_j (the V2V packet {id, x_hat, P, t}),
which enters as extra measurement noise S = H_j P_j H_j^T next to the radio's own noise R. The same
measurement relayed to j (``SeenFix``: a camera sighting on replayed data) tells j about itself: h
as seen from i's broadcast pose, S = H_i P_i H_i^T over i's [x, y, heading] (the fixes and their
measurement model: ``vehicle.models.cooperative_fixes``). Estimates of
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

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from bus.angles import wrap_angle
from vehicle.models import unscented as ut
from vehicle.models.cooperative_fixes import POSE, CooperativeFix, SeenFix, with_persisting_errors
from vehicle.models.kalman import UpdateResult
from vehicle.models.sym2 import Sym2, add_sym, as_array, inv_sym, sym

WEIGHT_GRID = np.linspace(0.0, 1.0, 101)  # w = 0: only the fix; w = 1: do not fuse
Fusion = Literal["split-ci", "ci", "paper", "naive"]
Weight = Literal["optimal", "closed-form"]


@dataclass(frozen=True)
class Correction:
    """A fused fix in measurement space: dz (2,) = z+ - z_hat, M (2, 2) before and M+ (2, 2) after,
    C (3, 2) = cov(pose, z), the weight w, and cov(x, z) (n, 2) of the whole state when the
    measurement is linear in the pose (None: through the regression on the pose, ``regression_on_z``)."""

    dz: np.ndarray
    M: np.ndarray
    M_new: np.ndarray
    C: np.ndarray
    w: float
    cov_xz: np.ndarray | None = None


@dataclass(frozen=True)
class CooperativeRule:
    """How a vehicle fuses a neighbour fix: see the module docstring. The 2 x 2 algebra of a fix runs on
    plain floats (numpy's per-call cost dominates 2 x 2 products; every ranging measurement pays it)."""

    fusion: Fusion = "split-ci"
    weight: Weight = "optimal"

    def fix_information(self, R: np.ndarray, S: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Information (k, 2, 2) the fix brings at weights w (k,): split CI (1 - w) ((1 - w) R + S)^-1
        = (R + S / (1 - w))^-1, plain CI (1 - w) (R + S)^-1, naive (R + S)^-1."""
        i00, i01, i11 = self._fix_information(sym(R), sym(S), np.asarray(w, dtype=float))
        return np.stack([np.stack([i00, i01], -1), np.stack([i01, i11], -1)], -2)

    def _fix_information(self, R: Sym2, S: Sym2, w):
        """``fix_information`` on floats or on 1-D arrays of weights, as (i00, i01, i11)."""
        if self.fusion == "naive":
            i00, i01, i11 = inv_sym(*add_sym(R, S))
            return i00 + 0.0 * w, i01 + 0.0 * w, i11 + 0.0 * w
        u = 1.0 - w
        if self.fusion == "split-ci":
            e00, e01, e11 = u * R[0] + S[0], u * R[1] + S[1], u * R[2] + S[2]
            f = u / (e00 * e11 - e01 * e01)
            return f * e11, -f * e01, f * e00
        q00, q01, q11 = inv_sym(*add_sym(R, S))
        return u * q00, u * q01, u * q11

    def choose_weight(self, M: np.ndarray, R: np.ndarray, S: np.ndarray) -> float:
        """w in [0, 1] for own covariance M (2, 2) of the measured quantity and the fix's noise R, S."""
        return self._weight(sym(M), sym(R), sym(S))

    def _weight(self, M: Sym2, R: Sym2, S: Sym2) -> float:
        if self.fusion == "naive":
            return 1.0
        if self.weight == "closed-form":
            return closed_form_weight(as_array(M), as_array(add_sym(R, S)))
        w = WEIGHT_GRID  # det(w M^-1 + fix information), the fused information about z (eq. 4.10)
        m00, m01, m11 = inv_sym(*M)
        i00, i01, i11 = self._fix_information(R, S, w)
        a, b, d = w * m00 + i00, w * m01 + i01, w * m11 + i11
        return float(w[int((a * d - b * b).argmax())])

    def fuse(
        self,
        x: np.ndarray,
        P: np.ndarray,
        fix: CooperativeFix | SeenFix,
        gate: float,
        unscented: bool = False,
        adapt: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray] | None = None,
        errors: dict | None = None,
    ) -> tuple[Correction | None, UpdateResult]:
        """Gate the fix on its plain NIS, choose w and fuse it in measurement space; None when gated
        out or when w = 1. ``unscented``: range and bearing through sigma points of the pose marginal
        (paper eqs. 4.1-4.9) instead of the linearization. ``adapt(y, M + S, R)``: the radio noise to
        use instead of R (IAE, vehicle.estimators.adaptive). ``errors``: the sighting's persisting errors as
        states of x (``vehicle.models.added_states.persisting_sighting``'s state arguments; linearized
        split CI and CI only)."""
        y, M, C, R, S, cov_xz = self.measurement(x, P, fix, unscented, errors)
        if adapt is not None:
            R = sym(adapt(np.array(y), as_array(add_sym(M, S)), as_array(R)))
        y0, y1 = y
        total = add_sym(M, R, S)
        t00, t01, t11 = inv_sym(*total)
        nis = t00 * y0 * y0 + 2.0 * t01 * y0 * y1 + t11 * y1 * y1
        result = UpdateResult(bool(nis <= gate), nis, nis / gate, (y0, y1), total)
        if not result.accepted:
            return None, result
        w = self._weight(M, R, S)
        if w >= 1.0 and self.fusion != "naive":
            return None, result
        i00, i01, i11 = self._fix_information(R, S, w)
        own = tuple(w * v for v in inv_sym(*M)) if w > 0.0 else (0.0, 0.0, 0.0)
        n00, n01, n11 = inv_sym(*add_sym(own, (i00, i01, i11)))
        g0, g1 = i00 * y0 + i01 * y1, i01 * y0 + i11 * y1  # fix information times y
        dz = np.array([n00 * g0 + n01 * g1, n01 * g0 + n11 * g1])
        return Correction(dz, as_array(M), as_array((n00, n01, n11)), C, w, cov_xz), result

    def measurement(
        self, x: np.ndarray, P: np.ndarray, fix: CooperativeFix | SeenFix, unscented: bool, errors: dict | None = None
    ) -> tuple[tuple[float, float], Sym2, np.ndarray, Sym2, Sym2, np.ndarray | None]:
        """Innovation y (2 floats), own covariance of the measured quantity M, the cross-covariance
        C = cov(pose, z) (3, 2), the independent noise R and the neighbour's share S (M, R, S as
        ``Sym2``), and cov(x, z) (n, 2) when the measurement is linear in the pose (else None).
        ``errors``: see :meth:`fuse`."""
        P_pp = P[:POSE, :POSE]
        if unscented and self.fusion != "paper":
            z_hat, M, C = ut.measure(x[:POSE], P_pp, fix.predicted, angle_rows=(1,))
            _, _, R, S = fix.linearized(x)
            y = (fix.range_m - float(z_hat[0]), wrap_angle(fix.bearing_rad - float(z_hat[1])))
            return y, sym(M), C, R, S, None
        if self.fusion == "paper":
            y, H, R, S = fix.implied(x, P_pp)
            y, R, S = tuple(y.tolist()), sym(R), sym(S)
        else:
            y, H, R, S = fix.linearized(x)
            if errors:
                y, H, R, idx = with_persisting_errors(x, fix, y, H, R, errors)
                cov_xz = P[:, idx] @ H.T
                return y, sym(H @ cov_xz[idx]), cov_xz[:POSE], R, S, cov_xz
        cov_xz = P[:, :POSE] @ H.T
        C = cov_xz[:POSE]
        return y, sym(H @ C), C, R, S, cov_xz


def closed_form_weight(M: np.ndarray, R: np.ndarray) -> float:
    """The w in [0, 1] maximising det(w M^-1 + (1 - w) R^-1) (plain CI of two 2 x 2 estimates) in
    closed form: with A = M^-1, B = R^-1, D = A - B it is the quadratic det(B) + w tr(adj(B) D) +
    w^2 det(D), so the best w is an end point or the vertex."""
    a00, a01, a11 = inv_sym(*sym(M))
    b00, b01, b11 = inv_sym(*sym(R))
    d00, d01, d11 = a00 - b00, a01 - b01, a11 - b11
    linear = b11 * d00 + b00 * d11 - 2.0 * b01 * d01  # tr(adj(B) D)
    quadratic = d00 * d11 - d01 * d01
    candidates = [0.0, 1.0]
    if quadratic < 0.0:
        candidates.append(min(max(-linear / (2.0 * quadratic), 0.0), 1.0))
    return max(candidates, key=lambda w: linear * w + quadratic * w * w)


def regression_on_z(P: np.ndarray, correction: Correction) -> np.ndarray:
    """A = cov(x, z) M^-1 (n, 2), with cov(x, z) = P_{.p} P_pp^-1 C (or as the correction carries it
    for a measurement linear in the pose): how every state follows z."""
    M_inv = as_array(inv_sym(*sym(correction.M)))
    if correction.cov_xz is not None:
        return correction.cov_xz @ M_inv
    return np.linalg.solve(P[:POSE, :POSE], P[:POSE, :]).T @ correction.C @ M_inv


def apply_correction(x: np.ndarray, P: np.ndarray, correction: Correction) -> tuple[np.ndarray, np.ndarray]:
    """The full state (n,) and covariance (n, n) after a fused fix (module docstring)."""
    A = regression_on_z(P, correction)
    x_new = x + A @ correction.dz
    x_new[2] = wrap_angle(x_new[2])
    P_new = P + A @ (correction.M_new - correction.M) @ A.T
    return x_new, 0.5 * (P_new + P_new.T)


def cooperative_update(
    x: np.ndarray,
    P: np.ndarray,
    fix: CooperativeFix | SeenFix,
    gate: float,
    rule: CooperativeRule = CooperativeRule(),
    unscented: bool = False,
) -> tuple[np.ndarray, np.ndarray, UpdateResult]:
    """One fix fused into (x (n,), P (n, n)) by ``rule``: the new state and covariance (unchanged when
    gated out or not worth fusing) and the gate's result."""
    correction, result = rule.fuse(x, P, fix, gate, unscented)
    if correction is None:
        return x, P, result
    x_new, P_new = apply_correction(x, P, correction)
    return x_new, P_new, result
