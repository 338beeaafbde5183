"""A neighbour fix as the cooperative rule (vehicle.models.cooperative) takes it, and its measurement
model (cooperative-localization paper, pure).

Vehicle i measures neighbour j: z = [range, bearing] with h = [|p_j - p_i|, atan2(dy, dx) - theta_i];
j's broadcast estimate p_j (covariance P_j) enters as S = H_j P_j H_j^T next to the radio's own noise R
(``CooperativeFix``). The same measurement relayed to j tells j about itself, h as seen from i's
broadcast pose, S = H_i P_i H_i^T over i's [x, y, heading] (``SeenFix``). Each gives its innovation,
Jacobian, R and S linearized (on floats: ``vehicle.models.sym2``), and the paper's implied-position form
(eqs. 4.10-4.11); a sighting's persisting range and bearing errors can enter as states
(``with_persisting_errors``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bus.angles import wrap_angle
from vehicle.models.added_states import in_columns, persisting_sighting
from vehicle.models.sym2 import Sym2, as_array, sym

POSE = 3


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
        return y, H, sym(self.covariance), sym(H_o @ self.observer_cov @ H_o.T)

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


def _along(dx: float, dy: float) -> tuple[tuple[float, float], tuple[float, float]]:
    """d [range, bearing] / d [dx, dy] of the offset (dx, dy) from observer to target, 2 x 2 by rows."""
    r2 = max(dx * dx + dy * dy, 1e-6)
    r = math.sqrt(r2)
    return (dx / r, dy / r), (-dy / r2, dx / r2)


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
    p, q, s = sym(fix.neighbour_cov_m2)
    S = (
        h00 * h00 * p + 2.0 * h00 * h01 * q + h01 * h01 * s,
        h00 * h10 * p + (h00 * h11 + h01 * h10) * q + h01 * h11 * s,
        h10 * h10 * p + 2.0 * h10 * h11 * q + h11 * h11 * s,
    )
    H = np.array([[h00, h01, 0.0], [h10, h11, -1.0]])
    return y, H, sym(fix.covariance), S


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
    H_full, R_white, stretched = persisting_sighting(H_full, as_array(R), predicted, x, **in_columns(errors, idx))
    return (
        (fix.range_m - float(stretched[0]), wrap_angle(fix.bearing_rad - float(stretched[1]))),
        H_full,
        sym(R_white),
        idx,
    )
