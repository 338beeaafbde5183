"""Two-view geometry for monocular visual odometry (AR-EKF-SLAM paper, its visual odometry section):
the normalised 8-point fundamental matrix inside RANSAC, ``E = K^T F K``, the SVD of E into R and t
with the cheirality check, least-squares (DLT) triangulation, and the choice between a homography and
a fundamental matrix by ORB-SLAM's score ratio (Mur-Artal et al. 2015, sec. IV-B): over flat ground
every point lies on one plane, the 8-point design matrix loses three ranks and F is not determined.
Pure numpy; points are pixel arrays (n, 2); an explicit seeded generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CHI2_ONE_DOF = 3.84  # ORB-SLAM's T_F: 95 % of chi-square, 1 dof (a point-to-line distance)
CHI2_TWO_DOF = 5.99  # T_H and the score's Gamma: 95 % of chi-square, 2 dof
HOMOGRAPHY_RATIO = 0.45  # R_H above this: the scene is (nearly) planar or the motion a rotation


def normalise(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Hartley's normalisation: homogeneous points (n, 3) with centroid 0 and mean distance sqrt(2),
    and the transform T (3, 3) that made them."""
    centre = points.mean(axis=0)
    spread = np.mean(np.linalg.norm(points - centre, axis=1))
    s = np.sqrt(2.0) / max(spread, 1e-12)
    T = np.array([[s, 0.0, -s * centre[0]], [0.0, s, -s * centre[1]], [0.0, 0.0, 1.0]])
    return np.column_stack([points, np.ones(len(points))]) @ T.T, T


def design_matrix(x1: np.ndarray, x2: np.ndarray) -> np.ndarray:
    """Rows (n, 9) of the epipolar constraint x2^T F x1 = 0 for homogeneous points (n, 3)."""
    return np.einsum("ni,nj->nij", x2, x1).reshape(len(x1), 9)


def eight_point(p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """The normalised 8-point fundamental matrix (3, 3), rank 2, unit Frobenius norm, from n >= 8
    correspondences (least squares for n > 8)."""
    x1, T1 = normalise(p1)
    x2, T2 = normalise(p2)
    F = np.linalg.svd(design_matrix(x1, x2))[2][-1].reshape(3, 3)
    U, S, Vt = np.linalg.svd(F)
    F = T2.T @ (U @ np.diag([S[0], S[1], 0.0]) @ Vt) @ T1
    return F / np.linalg.norm(F)


def homography_dlt(p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """The normalised DLT homography (3, 3) with x2 ~ H x1, from n >= 4 correspondences."""
    x1, T1 = normalise(p1)
    x2, T2 = normalise(p2)
    zero = np.zeros_like(x1)
    rows = np.concatenate(
        [
            np.hstack([zero, -x2[:, 2:3] * x1, x2[:, 1:2] * x1]),
            np.hstack([x2[:, 2:3] * x1, zero, -x2[:, 0:1] * x1]),
        ]
    )
    H = np.linalg.svd(rows)[2][-1].reshape(3, 3)
    H = np.linalg.inv(T2) @ H @ T1
    return H / H[2, 2] if abs(H[2, 2]) > 1e-12 else H


def epipolar_distances(F: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Squared distances (px^2) of each point to its epipolar line: of p2 to F p1, of p1 to F^T p2."""
    x1 = np.column_stack([p1, np.ones(len(p1))])
    x2 = np.column_stack([p2, np.ones(len(p2))])
    l2, l1 = x1 @ F.T, x2 @ F
    e = np.sum(x2 * l2, axis=1) ** 2
    return e / np.maximum(l2[:, 0] ** 2 + l2[:, 1] ** 2, 1e-30), e / np.maximum(l1[:, 0] ** 2 + l1[:, 1] ** 2, 1e-30)


def transfer_distances(H: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Squared transfer errors (px^2): of p2 against H p1 and of p1 against H^-1 p2."""

    def apply(M: np.ndarray, p: np.ndarray) -> np.ndarray:
        x = np.column_stack([p, np.ones(len(p))]) @ M.T
        return x[:, :2] / np.where(np.abs(x[:, 2:3]) < 1e-12, 1e-12, x[:, 2:3])

    try:
        Hinv = np.linalg.inv(H)
    except np.linalg.LinAlgError:
        return np.full(len(p1), np.inf), np.full(len(p1), np.inf)
    return np.sum((apply(H, p1) - p2) ** 2, axis=1), np.sum((apply(Hinv, p2) - p1) ** 2, axis=1)


def ransac(fit, distances, n_min: int, p1, p2, rng: np.random.Generator, *, threshold, iterations: int):
    """The model ``fit(p1, p2)`` with most inliers (every squared distance of ``distances(M, p1, p2)``
    under ``threshold``) over random minimal samples of ``n_min``, refitted on its inliers.
    Returns (model, inlier mask) or None (too few points, or no sample fitted)."""
    n = len(p1)
    if n < n_min:
        return None
    best = np.zeros(n, dtype=bool)
    for _ in range(iterations):
        pick = rng.choice(n, size=n_min, replace=False)
        try:
            model = fit(p1[pick], p2[pick])
        except np.linalg.LinAlgError:
            continue
        inliers = np.logical_and(*(d < threshold for d in distances(model, p1, p2)))
        if inliers.sum() > best.sum():
            best = inliers
    if best.sum() < n_min:
        return None
    return fit(p1[best], p2[best]), best


def orb_slam_score(distances: tuple[np.ndarray, np.ndarray], threshold: float, sigma_px: float) -> float:
    """S_M = sum over both directions of Gamma - d^2 / sigma^2 where d^2 / sigma^2 < T_M (ORB-SLAM eq. 3)."""
    score = 0.0
    for d in distances:
        z = d / sigma_px**2
        score += float(np.sum(np.where(z < threshold, CHI2_TWO_DOF - z, 0.0)))
    return score


@dataclass(frozen=True)
class ModelChoice:
    model: str  # "homography" or "fundamental"
    ratio: float  # R_H = S_H / (S_H + S_F)
    H: np.ndarray | None
    F: np.ndarray | None


def select_model(
    p1: np.ndarray, p2: np.ndarray, rng: np.random.Generator, *, sigma_px: float = 1.0, iterations: int = 200
) -> ModelChoice | None:
    """Fit both a homography and a fundamental matrix by RANSAC and keep the homography when
    R_H > 0.45 (ORB-SLAM). None: fewer than 8 correspondences or neither model fitted."""
    t = sigma_px**2
    h = ransac(homography_dlt, transfer_distances, 4, p1, p2, rng, threshold=CHI2_TWO_DOF * t, iterations=iterations)
    f = ransac(eight_point, epipolar_distances, 8, p1, p2, rng, threshold=CHI2_ONE_DOF * t, iterations=iterations)
    if h is None and f is None:
        return None
    s_h = orb_slam_score(transfer_distances(h[0], p1, p2), CHI2_TWO_DOF, sigma_px) if h else 0.0
    s_f = orb_slam_score(epipolar_distances(f[0], p1, p2), CHI2_ONE_DOF, sigma_px) if f else 0.0
    ratio = s_h / max(s_h + s_f, 1e-12)
    model = "homography" if ratio > HOMOGRAPHY_RATIO else "fundamental"
    return ModelChoice(model, ratio, h[0] if h else None, f[0] if f else None)


def decompose_essential(E: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """The four (R, t) of an essential matrix (Hartley & Zisserman result 9.19), t of unit norm."""
    U, _, Vt = np.linalg.svd(E)
    if np.linalg.det(U) < 0:
        U = -U
    if np.linalg.det(Vt) < 0:
        Vt = -Vt
    W = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    t = U[:, 2]
    return [(U @ W @ Vt, t), (U @ W @ Vt, -t), (U @ W.T @ Vt, t), (U @ W.T @ Vt, -t)]


def triangulate(P1: np.ndarray, P2: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> np.ndarray:
    """Least-squares (DLT) points (n, 3) seen at pixels p1 by camera P1 (3, 4) and p2 by P2."""
    A = np.stack(
        [
            p1[:, 0:1] * P1[2] - P1[0],
            p1[:, 1:2] * P1[2] - P1[1],
            p2[:, 0:1] * P2[2] - P2[0],
            p2[:, 1:2] * P2[2] - P2[1],
        ],
        axis=1,
    )  # (n, 4, 4)
    X = np.linalg.svd(A)[2][:, -1, :]
    w = np.where(np.abs(X[:, 3]) < 1e-12, 1e-12, X[:, 3])
    return X[:, :3] / w[:, None]


@dataclass(frozen=True)
class RelativePose:
    """Camera 2 in camera 1: X2 = R X1 + t (t of unit norm; metric only with a known scale) and the
    triangulated points (n, 3) in camera 1, with how many lie in front of both cameras."""

    R: np.ndarray
    t: np.ndarray
    points: np.ndarray
    in_front: int


def relative_pose(F: np.ndarray, K: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> RelativePose:
    """E = K^T F K, its four decompositions, and the one with most triangulated points in front of
    both cameras (the cheirality check)."""
    return most_in_front(decompose_essential(K.T @ F @ K), K, p1, p2)


def most_in_front(candidates, K: np.ndarray, p1: np.ndarray, p2: np.ndarray) -> RelativePose:
    """The cheirality check: of the candidate (R, t), the one with most of the pairs p1, p2 (n, 2)
    triangulated in front of both cameras (the first of equals)."""
    P1 = K @ np.hstack([np.eye(3), np.zeros((3, 1))])
    best = None
    for R, t in candidates:
        X = triangulate(P1, K @ np.hstack([R, t[:, None]]), p1, p2)
        front = int(np.sum((X[:, 2] > 0) & ((X @ R.T + t)[:, 2] > 0)))
        if best is None or front > best.in_front:
            best = RelativePose(R, t, X, front)
    return best


def translation_given_rotation(
    R: np.ndarray,
    K: np.ndarray,
    p1: np.ndarray,
    p2: np.ndarray,
    rng: np.random.Generator,
    *,
    threshold_px: float = 1.5,
    iterations: int = 200,
) -> tuple[RelativePose, np.ndarray] | None:
    """Camera 2's direction of travel when its rotation R (X2 = R X1 + t) is known (from an attitude
    sensor): the epipolar constraint x2^T [t]x R x1 = 0 is linear in t, t . (R x1 x x2) = 0 for the
    normalised rays x, so two pairs give t and RANSAC keeps the pairs within ``threshold_px`` of their
    epipolar lines (F = K^-T [t]x R K^-1) both ways; t is refitted on them by least squares and its sign
    chosen by cheirality. Two unknowns instead of the essential matrix's five: well posed where F is
    not (a forward-looking camera moving forward has its epipole in the frame). Returns the pose with
    t of unit norm and the inlier mask (p1's), or None (fewer than two pairs, no sample fitted)."""
    K_inv = np.linalg.inv(K)
    rays1 = np.column_stack([p1, np.ones(len(p1))]) @ K_inv.T
    rays2 = np.column_stack([p2, np.ones(len(p2))]) @ K_inv.T
    constraints = np.cross(rays1 @ R.T, rays2)  # (n, 3): t . a_i = 0
    pairs = np.hstack([p1, p2])  # (n, 4): what the distances are measured on

    def fit(a: np.ndarray, _: np.ndarray) -> np.ndarray:
        return np.linalg.svd(a)[2][-1]  # t: the null vector of the sample's constraints

    def distances(t: np.ndarray, _: np.ndarray, both: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        skew = np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
        return epipolar_distances(K_inv.T @ skew @ R @ K_inv, both[:, :2], both[:, 2:])

    fitted = ransac(fit, distances, 2, constraints, pairs, rng, threshold=threshold_px**2, iterations=iterations)
    if fitted is None:
        return None
    t, inliers = fitted
    return most_in_front(((R, t), (R, -t)), K, p1[inliers], p2[inliers]), inliers
