"""EKF-SLAM core (vision EKF-SLAM paper): a pose and a growing map of 2-D landmarks. Pure functions.

State ``x = [pose (p,), l1x, l1y, l2x, l2y, ...]`` with the pose's first three entries ``[x m, y m,
theta rad]`` (p = 3 as in the paper; p = 4 carries the unicycle EKF's gyro bias too), covariance
``P`` (n, n), n = p + 2 m for m landmarks.

- Observation of landmark j (paper, range-bearing model): with dx = l_jx - x, dy = l_jy - y,
  ``h = [sqrt(dx^2 + dy^2), atan2(dy, dx) - theta]`` (the paper writes phi = x - l_x, psi = y - l_y
  and atan2(-psi, -phi): the same bearing).
- Landmark initialisation (paper): ``g(x, z) = [x + r cos(b + theta), y + r sin(b + theta)]`` with
  ``Gx = dg/dpose`` (2, 3) and ``Gz = dg/dz`` (2, 2); the covariance grows as ``P <- Y P Y^T`` with
  ``Y = [[I, 0], [Gx 0, Gz]]``, i.e. new cross terms ``Gx P_pose,:`` and the block
  ``Gx P_pp Gx^T + Gz R Gz^T``.
- First-estimates Jacobians (Huang, Mourikis and Roumeliotis, "Analysis and improvement of the
  consistency of EKF-based SLAM", ICRA 2008): evaluated at the estimates of the moment, the
  Jacobians give the filter information about the global heading it cannot have (a revisit
  collapses its variance below the launch prior's), and loop closures turn it overconfident. With
  each landmark's first estimate and the pose's propagated (pre-update) estimate in H, and the
  propagated positions in F, the unobservable translation and rotation stay unobservable.
- Sequential per-landmark updates (paper). An update touches P in place: the gain comes from the
  five columns of P the observation depends on (O(n)), and ``P -= K S K^T`` is applied as two rank-1
  BLAS updates on P's own memory (O(n^2) flops, no n x n temporary), exactly symmetric.
"""

from __future__ import annotations

import math

import numpy as np

from bus.angles import wrap_angle
from vehicle.models.cooperative import Correction, regression_on_z
from vehicle.models.kalman import UpdateResult


def landmark_count(x: np.ndarray, pose_dim: int) -> int:
    return (len(x) - pose_dim) // 2


def observe(
    x: np.ndarray, pose_dim: int, j: int, linearize_at: tuple[np.ndarray, np.ndarray] | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Predicted [range m, bearing rad] (2,) of landmark j, and the Jacobians H_pose = dh/d[x, y,
    theta] (2, 3) and H_landmark = dh/d[l_jx, l_jy] (2, 2), evaluated at the estimate or at
    ``linearize_at`` = (vehicle xy (2,), landmark xy (2,)) (first-estimates Jacobians, below)."""
    k = pose_dim + 2 * j
    dx, dy = x[k] - x[0], x[k + 1] - x[1]
    predicted = np.array([math.hypot(dx, dy), wrap_angle(math.atan2(dy, dx) - x[2])])
    if linearize_at is not None:
        (px, py), (lx, ly) = linearize_at
        dx, dy = lx - px, ly - py
    q = max(dx * dx + dy * dy, 1e-12)
    r = math.sqrt(q)
    H_pose = np.array([[-dx / r, -dy / r, 0.0], [dy / q, -dx / q, -1.0]])
    H_landmark = np.array([[dx / r, dy / r], [-dy / q, dx / q]])
    return predicted, H_pose, H_landmark


def landmark_from(pose: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where a landmark seen at z = [range m, bearing rad] from ``pose`` (3+,) lies (2,), with
    Gx = dg/d[x, y, theta] (2, 3) and Gz = dg/d[range, bearing] (2, 2) (paper's initialisation)."""
    r, a = z[0], z[1] + pose[2]
    c, s = math.cos(a), math.sin(a)
    point = np.array([pose[0] + r * c, pose[1] + r * s])
    Gx = np.array([[1.0, 0.0, -r * s], [0.0, 1.0, r * c]])
    Gz = np.array([[c, -r * s], [s, r * c]])
    return point, Gx, Gz


def add_landmarks(x: np.ndarray, P: np.ndarray, zs: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Append landmarks observed at ``zs`` (k, 2) with noise R (2, 2), or one per landmark (k, 2, 2):
    the augmented (x, P), one new
    allocation for the whole batch (the map grows once per camera frame, not per landmark).
    P <- Y P Y^T (paper) block by block: cov(l_i, old state) = Gx_i P[pose, :],
    cov(l_i, l_i') = Gx_i P_pp Gx_i'^T (they share the pose error), var(l_i) adds Gz_i R Gz_i^T."""
    n, k = len(x), len(zs)
    inits = [landmark_from(x, z) for z in zs]
    G = np.vstack([Gx for _, Gx, _ in inits])  # (2k, 3)
    x_new = np.concatenate([x, *(point for point, _, _ in inits)])
    P_new = np.empty((n + 2 * k, n + 2 * k))
    P_new[:n, :n] = P
    cross = G @ P[:3, :]  # (2k, n)
    P_new[n:, :n] = cross
    P_new[:n, n:] = cross.T
    P_new[n:, n:] = G @ P[:3, :3] @ G.T
    Rs = np.broadcast_to(R, (k, 2, 2))
    for i, (_, _, Gz) in enumerate(inits):
        P_new[n + 2 * i : n + 2 * i + 2, n + 2 * i : n + 2 * i + 2] += Gz @ Rs[i] @ Gz.T
    return x_new, P_new


def update(
    x: np.ndarray,
    P: np.ndarray,
    pose_dim: int,
    j: int,
    z: np.ndarray,
    R: np.ndarray,
    gate: float,
    linearize_at: tuple[np.ndarray, np.ndarray] | None = None,
) -> UpdateResult:
    """EKF update with landmark j seen at z = [range m, bearing rad] (noise R (2, 2)), in place on
    x (n,) and P (n, n, C-contiguous); skipped when the NIS is above ``gate``. ``linearize_at``:
    see :func:`observe`."""
    predicted, H_pose, H_landmark = observe(x, pose_dim, j, linearize_at)
    k = pose_dim + 2 * j
    y = np.array([z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
    return update_in_place(x, P, [0, 1, 2, k, k + 1], np.hstack([H_pose, H_landmark]), y, R, gate)


def update_in_place(
    x: np.ndarray, P: np.ndarray, idx: list[int], H: np.ndarray, y: np.ndarray, R: np.ndarray, gate: float
) -> UpdateResult:
    """EKF update with innovation y (2,) of a measurement depending only on the states ``idx`` (q,)
    through H (2, q), noise R (2, 2), in place on x (n,) and P (n, n, C-contiguous); skipped when the
    NIS is above ``gate``. O(n) for the gain, O(n^2) flops for P, no n x n temporary. A one-dimensional
    measurement (y (1,), H (1, q), R (1, 1)) is one rank-1 update (:func:`update_in_place_1d`)."""
    if len(y) == 1:
        return update_in_place_1d(x, P, idx, H, y, R, gate)
    PHt = P[:, idx] @ H.T  # (n, 2) = P H^T
    (a, b), (_, d) = (H @ PHt[idx] + R).tolist()  # S, symmetric 2 x 2: in closed form below
    y0, y1 = y.tolist()
    if not math.isfinite(a + b + d + y0 + y1):
        return UpdateResult(False, math.nan, math.nan)  # gated out, as a NaN NIS always was
    l11 = math.sqrt(a) if a > 0.0 else math.nan
    l21 = b / l11
    l22 = math.sqrt(d - l21 * l21) if d - l21 * l21 > 0.0 else math.nan
    if not (math.isfinite(l11) and math.isfinite(l22)):
        raise np.linalg.LinAlgError("innovation covariance is not positive definite")
    w0 = y0 / l11  # w = L^-1 y, S = L L^T
    w1 = (y1 - l21 * w0) / l22
    nis = w0 * w0 + w1 * w1
    if not nis <= gate:
        return UpdateResult(False, nis, nis / gate)
    # P -= PHt S^-1 PHt^T = A A^T with A = PHt L^-T: two rank-1 updates in place; x += A^T w
    row0 = PHt[:, 0] / l11
    row1 = (PHt[:, 1] - l21 * row0) / l22
    x += w0 * row0 + w1 * row1
    x[2] = wrap_angle(x[2])
    from scipy.linalg.blas import dger  # BLAS rank-1 update in place (imported here: SLAM vehicles only)

    for row in (row0, row1):
        dger(-1.0, row, row, a=P.T, overwrite_a=True)
    return UpdateResult(True, nis, nis / gate)


def update_in_place_1d(
    x: np.ndarray, P: np.ndarray, idx: list[int], H: np.ndarray, y: np.ndarray, R: np.ndarray, gate: float
) -> UpdateResult:
    """:func:`update_in_place` for a one-dimensional measurement (a heading): S = H P H^T + R a scalar,
    P -= a a^T with a = P H^T / sqrt(S), x += a y / sqrt(S)."""
    PHt = P[:, idx] @ H[0]  # (n,)
    S = float(H[0] @ PHt[idx] + R[0, 0])
    if not (math.isfinite(S) and math.isfinite(float(y[0]))) or S <= 0.0:
        return UpdateResult(False, math.nan, math.nan)
    w = float(y[0]) / math.sqrt(S)
    nis = w * w
    if not nis <= gate:
        return UpdateResult(False, nis, nis / gate)
    a = PHt / math.sqrt(S)
    x += w * a
    x[2] = wrap_angle(x[2])
    from scipy.linalg.blas import dger

    dger(-1.0, a, a, a=P.T, overwrite_a=True)
    return UpdateResult(True, nis, nis / gate)


def predict_pose(x: np.ndarray, P: np.ndarray, F: np.ndarray, Q: np.ndarray, pose_next: np.ndarray) -> None:
    """Motion of the pose block (q = len(pose_next)) in place: x_pose <- pose_next, P_pp <- F P_pp F^T + Q,
    cross terms P_pl <- F P_pl (landmarks do not move). F, Q (q, q)."""
    q = len(pose_next)
    x[:q] = pose_next
    x[2] = wrap_angle(x[2])
    P[:q, q:] = F @ P[:q, q:]
    P[q:, :q] = P[:q, q:].T
    P[:q, :q] = F @ P[:q, :q] @ F.T + Q


def apply_correction_in_place(x: np.ndarray, P: np.ndarray, correction: Correction) -> None:
    """``apply_correction`` on a large state (a SLAM map, P C-contiguous) without n x n temporaries:
    the change of P is A D A^T with D = M+ - M (2, 2), applied as two rank-1 updates."""
    A = regression_on_z(P, correction)
    x += A @ correction.dz
    x[2] = wrap_angle(x[2])
    values, vectors = np.linalg.eigh(correction.M_new - correction.M)
    from scipy.linalg.blas import dger  # BLAS rank-1 update in place (imported here: SLAM vehicles only)

    for value, u in zip(values, (A @ vectors).T):
        dger(float(value), u, u, a=P.T, overwrite_a=True)


def add_landmark_with_errors(
    x: np.ndarray, P: np.ndarray, z: np.ndarray, R_white: np.ndarray, range_state: int | None, bearing_state: int | None
) -> tuple[np.ndarray, np.ndarray]:
    """Append a landmark seen at z = [range m, bearing rad] when the range reads r (1 + s) + white
    and the bearing beta + b + white, s and b the states at ``range_state`` and ``bearing_state``
    (vehicle.models.added_states; either may be None), R_white (2, 2) the white noise: the paper's g(x, z)
    at r = z_r / (1 + s), beta = z_b - b, with those states among the ones the landmark depends on
    (G over [x, y, theta, s, b]), so that later sightings with the same errors do not count them
    twice. The augmented (x, P)."""
    stretch = 1.0 + (float(x[range_state]) if range_state is not None else 0.0)
    offset = float(x[bearing_state]) if bearing_state is not None else 0.0
    point, Gx, Gz = landmark_from(x, np.array([z[0] / stretch, z[1] - offset]))
    idx, G = [0, 1, 2], [Gx]
    if range_state is not None:
        idx.append(range_state)
        G.append(-(point - x[:2])[:, None] / stretch)  # d l / d s
    if bearing_state is not None:
        idx.append(bearing_state)
        G.append(-Gz[:, 1:2])  # d l / d b = -d l / d beta
    Gz[:, 0] /= stretch  # d l / d z_r
    G = np.hstack(G)
    n = len(x)
    P_new = np.empty((n + 2, n + 2))
    P_new[:n, :n] = P
    cross = G @ P[idx, :]
    P_new[n:, :n] = cross
    P_new[:n, n:] = cross.T
    P_new[n:, n:] = G @ P[np.ix_(idx, idx)] @ G.T + Gz @ R_white @ Gz.T
    return np.concatenate([x, point]), P_new
