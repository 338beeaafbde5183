"""Cooperative localization from relative measurements (cooperative-localization paper, pure).

Vehicle i measures neighbour j: z = [range, bearing] with h = [|p_j - p_i|, atan2(dy, dx) - theta_i].
Neighbour j broadcasts its own estimate p_j with covariance P_j (the V2V packet {id, x_hat, P, t}),
which enters as extra measurement noise S = H_j P_j H_j^T next to the radio's own noise R. The same
measurement relayed to j (``SeenFix``: a camera sighting on replayed data) tells j about itself: h
as seen from i's broadcast pose, S = H_i P_i H_i^T over i's [x, y, heading]. Estimates of
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

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from bus.angles import wrap_angle
from vehicle.kalman import UpdateResult
from vehicle.models import unscented as ut
from vehicle.models.added_states import in_columns, persisting_sighting

POSE = 3
WEIGHT_GRID = np.linspace(0.0, 1.0, 101)  # w = 0: only the fix; w = 1: do not fuse
Fusion = Literal["split-ci", "ci", "paper", "naive"]
Weight = Literal["optimal", "closed-form"]
Sym2 = tuple[float, float, float]  # a symmetric 2 x 2 matrix as (a00, a01, a11): the fix's algebra on floats


@dataclass(frozen=True)
class CooperativeFix:
    """A ranging measurement paired with the neighbour's broadcast estimate at the same stamp."""

    vehicle_id: int
    stamp_us: int
    seq: int
    target_id: int
    range_m: float
    bearing_rad: float
    covariance: np.ndarray  # (2, 2) over [range m, bearing rad]
    neighbour_xy_m: np.ndarray  # (2,)
    neighbour_cov_m2: np.ndarray  # (2, 2)
    neighbour_accuses: frozenset[int] = frozenset()  # whom the neighbour's broadcast says it distrusts

    def predicted(self, pose: np.ndarray) -> np.ndarray:
        """[range, bearing] (2,) expected from own pose (3,)."""
        return relative_model(pose, self.neighbour_xy_m)[0]

    def linearized(self, x: np.ndarray) -> tuple[tuple[float, float], np.ndarray, Sym2, Sym2]:
        return _linearized(x, self)

    def implied(self, x: np.ndarray, P_pp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return implied_position(x, P_pp, self)

    def own_jacobian(self, x: np.ndarray) -> tuple[tuple[float, float], tuple[float, float]]:
        """d h / d(own position), 2 x 2 by rows, at state x (n,) (relative_model's H[:, :2], on floats)."""
        (nx, ny), (px, py) = self.neighbour_xy_m.tolist(), x[:2].tolist()
        (a, b), (c, d) = _along(nx - px, ny - py)
        return (-a, -b), (-c, -d)  # own position enters the offset with a minus sign


@dataclass(frozen=True)
class SeenFix:
    """A neighbour's sighting of this vehicle (relayed to it) paired with the observer's broadcast
    pose at the same stamp: z = [range, bearing] with h = [|p_i - p_o|, atan2(dy, dx) - theta_o]
    (d = p_i - p_o), the observer's pose error entering as S = H_o P_o H_o^T over [x, y, yaw]."""

    vehicle_id: int
    stamp_us: int
    seq: int
    observer_id: int
    range_m: float
    bearing_rad: float
    covariance: np.ndarray  # (2, 2) over [range m, bearing rad]
    observer_pose: np.ndarray  # (3,) [x m, y m, yaw rad]
    observer_cov: np.ndarray  # (3, 3)
    neighbour_accuses: frozenset[int] = frozenset()  # whom the observer's broadcast says it distrusts

    def predicted(self, pose: np.ndarray) -> np.ndarray:
        """[range, bearing] (2,) the observer should have seen with this vehicle at ``pose`` (3,)."""
        dx, dy = pose[0] - self.observer_pose[0], pose[1] - self.observer_pose[1]
        return np.array([np.hypot(dx, dy), wrap_angle(np.arctan2(dy, dx) - self.observer_pose[2])])

    def linearized(self, x: np.ndarray) -> tuple[tuple[float, float], np.ndarray, Sym2, Sym2]:
        """Innovation y, H = dh/dx_pose (2, 3) (no heading term: the bearing is the observer's), R and S."""
        px, py = x[:2].tolist()
        ox, oy, oyaw = self.observer_pose.tolist()
        dx, dy = px - ox, py - oy
        r2 = max(dx * dx + dy * dy, 1e-6)
        r = math.sqrt(r2)
        y = (self.range_m - r, wrap_angle(self.bearing_rad - wrap_angle(math.atan2(dy, dx) - oyaw)))
        H = np.array([[dx / r, dy / r, 0.0], [-dy / r2, dx / r2, 0.0]])
        H_o = np.array([[-dx / r, -dy / r, 0.0], [dy / r2, -dx / r2, -1.0]])
        return y, H, _sym(self.covariance), _sym(H_o @ self.observer_cov @ H_o.T)

    def own_jacobian(self, x: np.ndarray) -> tuple[tuple[float, float], tuple[float, float]]:
        """d h / d(own position), 2 x 2 by rows, at state x (n,) (``linearized``'s H[:, :2], on floats)."""
        (ox, oy), (px, py) = self.observer_pose[:2].tolist(), x[:2].tolist()
        return _along(px - ox, py - oy)

    def implied(self, x: np.ndarray, P_pp: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The paper's form: own position as the sighting implies it, p = p_o + r [cos, sin](theta_o +
        beta), with P = G P_o G^T + J R J^T (G = dp / d pose_o, J = dp / d[r, beta]); H = [I 0], R = 0."""
        angle = self.observer_pose[2] + self.bearing_rad
        c, s = np.cos(angle), np.sin(angle)
        p = self.observer_pose[:2] + self.range_m * np.array([c, s])
        G = np.array([[1.0, 0.0, -self.range_m * s], [0.0, 1.0, self.range_m * c]])
        J = np.array([[c, -self.range_m * s], [s, self.range_m * c]])
        return p - x[:2], np.eye(2, POSE), np.zeros((2, 2)), G @ self.observer_cov @ G.T + J @ self.covariance @ J.T


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


def _along(dx: float, dy: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """d [range, bearing] / d [dx, dy] of the offset (dx, dy) from observer to target, 2 x 2 by rows."""
    r2 = max(dx * dx + dy * dy, 1e-6)
    r = math.sqrt(r2)
    return (dx / r, dy / r), (-dy / r2, dx / r2)


def _sym(A: np.ndarray) -> Sym2:
    """(a00, a01, a11) of a symmetric 2 x 2 array."""
    (a, b), (_, d) = A.tolist()
    return a, b, d


def _inv_sym(a: float, b: float, d: float) -> Sym2:
    det = a * d - b * b
    return d / det, -b / det, a / det


def _add_sym(*terms: Sym2) -> Sym2:
    """The sum of symmetric 2 x 2 matrices, entry by entry in ``sum``'s order (from 0.0)."""
    a = b = d = 0.0
    for t0, t1, t2 in terms:
        a, b, d = a + t0, b + t1, d + t2
    return a, b, d


def _array(a: Sym2) -> np.ndarray:
    return np.array([[a[0], a[1]], [a[1], a[2]]])


def relative_model(x: np.ndarray, neighbour_xy_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted [range, bearing] (2,), H = dh/dx_i (2, n) and H_j = dh/dp_j (2, 2) for state x (n,)."""
    dx, dy = neighbour_xy_m - x[:2]
    r2 = max(dx * dx + dy * dy, 1e-6)
    r = np.sqrt(r2)
    H = np.zeros((2, len(x)))
    H[0, :2] = [-dx / r, -dy / r]
    H[1, :3] = [dy / r2, -dx / r2, -1.0]
    return np.array([r, wrap_angle(np.arctan2(dy, dx) - x[2])]), H, -H[:, :2]


def implied_position(
    x: np.ndarray, P_pp: np.ndarray, fix: CooperativeFix
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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
    """How a vehicle fuses a neighbour fix: see the module docstring. The 2 x 2 algebra of a fix runs on
    plain floats (numpy's per-call cost dominates 2 x 2 products; every ranging measurement pays it)."""

    fusion: Fusion = "split-ci"
    weight: Weight = "optimal"

    def fix_information(self, R: np.ndarray, S: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Information (k, 2, 2) the fix brings at weights w (k,): split CI (1 - w) ((1 - w) R + S)^-1
        = (R + S / (1 - w))^-1, plain CI (1 - w) (R + S)^-1, naive (R + S)^-1."""
        i00, i01, i11 = self._fix_information(_sym(R), _sym(S), np.asarray(w, dtype=float))
        return np.stack([np.stack([i00, i01], -1), np.stack([i01, i11], -1)], -2)

    def _fix_information(self, R: Sym2, S: Sym2, w):
        """``fix_information`` on floats or on 1-D arrays of weights, as (i00, i01, i11)."""
        if self.fusion == "naive":
            i00, i01, i11 = _inv_sym(*_add_sym(R, S))
            return i00 + 0.0 * w, i01 + 0.0 * w, i11 + 0.0 * w
        u = 1.0 - w
        if self.fusion == "split-ci":
            e00, e01, e11 = u * R[0] + S[0], u * R[1] + S[1], u * R[2] + S[2]
            f = u / (e00 * e11 - e01 * e01)
            return f * e11, -f * e01, f * e00
        q00, q01, q11 = _inv_sym(*_add_sym(R, S))
        return u * q00, u * q01, u * q11

    def choose_weight(self, M: np.ndarray, R: np.ndarray, S: np.ndarray) -> float:
        """w in [0, 1] for own covariance M (2, 2) of the measured quantity and the fix's noise R, S."""
        return self._weight(_sym(M), _sym(R), _sym(S))

    def _weight(self, M: Sym2, R: Sym2, S: Sym2) -> float:
        if self.fusion == "naive":
            return 1.0
        if self.weight == "closed-form":
            return closed_form_weight(_array(M), _array(_add_sym(R, S)))
        w = WEIGHT_GRID  # det(w M^-1 + fix information), the fused information about z (eq. 4.10)
        m00, m01, m11 = _inv_sym(*M)
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
        use instead of R (IAE, vehicle.adaptive). ``errors``: the sighting's persisting errors as
        states of x (``vehicle.models.added_states.persisting_sighting``'s state arguments; linearized
        split CI and CI only)."""
        y, M, C, R, S, cov_xz = self.measurement(x, P, fix, unscented, errors)
        if adapt is not None:
            R = _sym(adapt(np.array(y), _array(_add_sym(M, S)), _array(R)))
        y0, y1 = y
        total = _add_sym(M, R, S)
        t00, t01, t11 = _inv_sym(*total)
        nis = t00 * y0 * y0 + 2.0 * t01 * y0 * y1 + t11 * y1 * y1
        result = UpdateResult(bool(nis <= gate), nis, nis / gate, (y0, y1), total)
        if not result.accepted:
            return None, result
        w = self._weight(M, R, S)
        if w >= 1.0 and self.fusion != "naive":
            return None, result
        i00, i01, i11 = self._fix_information(R, S, w)
        own = tuple(w * v for v in _inv_sym(*M)) if w > 0.0 else (0.0, 0.0, 0.0)
        n00, n01, n11 = _inv_sym(*_add_sym(own, (i00, i01, i11)))
        g0, g1 = i00 * y0 + i01 * y1, i01 * y0 + i11 * y1  # fix information times y
        dz = np.array([n00 * g0 + n01 * g1, n01 * g0 + n11 * g1])
        return Correction(dz, _array(M), _array((n00, n01, n11)), C, w, cov_xz), result

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
            return y, _sym(M), C, R, S, None
        if self.fusion == "paper":
            y, H, R, S = fix.implied(x, P_pp)
            y, R, S = tuple(y.tolist()), _sym(R), _sym(S)
        else:
            y, H, R, S = fix.linearized(x)
            if errors:
                y, H, R, idx = with_persisting_errors(x, fix, y, H, R, errors)
                cov_xz = P[:, idx] @ H.T
                return y, _sym(H @ cov_xz[idx]), cov_xz[:POSE], R, S, cov_xz
        cov_xz = P[:, :POSE] @ H.T
        C = cov_xz[:POSE]
        return y, _sym(H @ C), C, R, S, cov_xz


def _linearized(x: np.ndarray, fix: CooperativeFix) -> tuple[tuple[float, float], np.ndarray, Sym2, Sym2]:
    """``neighbour_measurement`` on floats: the innovation y, H = dh/dx_pose (2, 3), R and
    S = H_j P_j H_j^T (H_j = -H[:, :2])."""
    px, py, theta = x[:POSE].tolist()
    nx, ny = fix.neighbour_xy_m.tolist()
    dx, dy = nx - px, ny - py
    r2 = max(dx * dx + dy * dy, 1e-6)
    r = math.sqrt(r2)
    y = (fix.range_m - r, wrap_angle(fix.bearing_rad - wrap_angle(math.atan2(dy, dx) - theta)))
    h00, h01, h10, h11 = -dx / r, -dy / r, dy / r2, -dx / r2
    p, q, s = _sym(fix.neighbour_cov_m2)
    S = (
        h00 * h00 * p + 2.0 * h00 * h01 * q + h01 * h01 * s,
        h00 * h10 * p + (h00 * h11 + h01 * h10) * q + h01 * h11 * s,
        h10 * h10 * p + 2.0 * h10 * h11 * q + h11 * h11 * s,
    )
    H = np.array([[h00, h01, 0.0], [h10, h11, -1.0]])
    return y, H, _sym(fix.covariance), S


def with_persisting_errors(
    x: np.ndarray, fix: CooperativeFix | SeenFix, y: tuple[float, float], H: np.ndarray, R: Sym2, errors: dict
) -> tuple[tuple[float, float], np.ndarray, Sym2, list[int]]:
    """A sighting's linearized model (innovation y, H (2, 3) over the pose, reported noise R) with its
    persisting range and bearing errors as the states ``errors`` names (vehicle.models.added_states): y,
    H (2, q) over the states ``idx`` (q,) = [x, y, theta, the error states], the white part of R."""
    idx = [0, 1, 2] + [
        errors[key] for key in ("range_state", "bearing_state", "scale_state") if errors.get(key) is not None
    ]
    predicted = np.array([fix.range_m - y[0], fix.bearing_rad - y[1]])
    H_full = np.zeros((2, len(idx)))
    H_full[:, :POSE] = H
    H_full, R_white, stretched = persisting_sighting(H_full, _array(R), predicted, x, **in_columns(errors, idx))
    return (
        (fix.range_m - float(stretched[0]), wrap_angle(fix.bearing_rad - float(stretched[1]))),
        H_full,
        _sym(R_white),
        idx,
    )


def closed_form_weight(M: np.ndarray, R: np.ndarray) -> float:
    """The w in [0, 1] maximising det(w M^-1 + (1 - w) R^-1) (plain CI of two 2 x 2 estimates) in
    closed form: with A = M^-1, B = R^-1, D = A - B it is the quadratic det(B) + w tr(adj(B) D) +
    w^2 det(D), so the best w is an end point or the vertex."""
    a00, a01, a11 = _inv_sym(*_sym(M))
    b00, b01, b11 = _inv_sym(*_sym(R))
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
    M_inv = _array(_inv_sym(*_sym(correction.M)))
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
