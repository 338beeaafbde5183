"""A landmark's position from two frames, as the AR-EKF-SLAM paper computes it, with the covariance its
EKF needs (the paper gives the point, not its uncertainty). Pure.

The paper's equation (1): z_ci [u_i, v_i, 1]^T = m^i [X, 1]^T for the two frames, m^1 = K [I | 0],
m^2 = K [R | L]; eliminating z_ci gives its four linear equations in X = [x, y, z] (one per pixel
coordinate), for example (u_1 m^1_31 - m^1_11) x + (u_1 m^1_32 - m^1_12) y + (u_1 m^1_33 - m^1_13) z =
m^1_14 - u_1 m^1_34, solved by least squares: A(u) X = b(u) (4 x 3), X = (A^T A)^-1 A^T b.

Covariance. The pixels' noise (sigma_px per coordinate, independent) moves X by the derivative of the
least-squares solution, dX/du_k = (A^T A)^-1 [dA_k^T (b - A X) + A^T (db_k - dA_k X)] (the first term
is the residual's, zero for a noise-free pair), so cov X = J diag(sigma_px^2) J^T with J (3, 4). Along
the ray the two lines of sight meet at the parallax angle: a short baseline or a far point makes that
angle small and the ellipsoid long and thin along the ray (its long axis grows as 1 / parallax).

Refused, never returned as points (``Refused``): a point behind either camera (the paper's
cheirality condition), and two rays that hardly cross (parallax below ``MIN_PARALLAX_RAD``): a pure
rotation (no baseline) or a point too far for the baseline, where A^T A is near singular and X is
anything along the ray.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_PARALLAX_RAD = np.deg2rad(0.5)  # rays closer than this say nothing about depth


@dataclass(frozen=True)
class Triangulated:
    """Points (n, 3) in the first camera's frame, their covariances (n, 3, 3), the parallax (n,) in rad,
    and ``usable`` (n,): False where refused (``refusal`` says why: "", "behind", "parallax")."""

    points: np.ndarray
    covariances: np.ndarray
    parallax_rad: np.ndarray
    refusal: np.ndarray

    @property
    def usable(self) -> np.ndarray:
        return self.refusal == ""


def camera_matrices(K: np.ndarray, R: np.ndarray, L: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """m^1 = K [I | 0] and m^2 = K [R | L] (3, 4) of the paper's equation (1): X_2 = R X_1 + L."""
    return K @ np.hstack([np.eye(3), np.zeros((3, 1))]), K @ np.hstack([R, np.reshape(L, (3, 1))])


def linear_system(m1: np.ndarray, m2: np.ndarray, uv1: np.ndarray, uv2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The paper's four equations for n points: A (n, 4, 3) and b (n, 4), rows u_1, v_1, u_2, v_2."""
    rows = []
    for m, uv in ((m1, uv1), (m2, uv2)):
        for coordinate in (0, 1):
            w = uv[:, coordinate : coordinate + 1]
            rows.append((w * m[2, :3] - m[coordinate, :3], m[coordinate, 3] - w[:, 0] * m[2, 3]))
    return np.stack([a for a, _ in rows], axis=1), np.stack([b for _, b in rows], axis=1)


def triangulate(
    m1: np.ndarray, m2: np.ndarray, uv1: np.ndarray, uv2: np.ndarray, *, sigma_px: float = 1.0
) -> Triangulated:
    """Points seen at pixels uv1 (n, 2) by camera m1 (3, 4) and uv2 by m2 (module docstring)."""
    A, b, AtA, X = _least_squares(m1, m2, uv1, uv2)
    residual = b - np.einsum("nkj,nj->nk", A, X)
    J = np.empty((len(X), 3, 4))
    for k, m in enumerate((m1, m1, m2, m2)):  # d(row k)/d(its pixel coordinate): dA_k = m_3, db_k = -m_34
        dA = np.zeros((len(X), 4, 3))
        dA[:, k] = m[2, :3]
        db = np.zeros((len(X), 4))
        db[:, k] = -m[2, 3]
        rhs = np.einsum("nki,nk->ni", dA, residual) + np.einsum("nki,nk->ni", A, db - np.einsum("nkj,nj->nk", dA, X))
        J[:, :, k] = np.linalg.solve(AtA, rhs[..., None])[..., 0]
    covariances = sigma_px**2 * np.einsum("nik,njk->nij", J, J)
    parallax = _parallax(m1, m2, X)
    depth2 = np.einsum("j,nj->n", m2[2, :3], X) + m2[2, 3]
    refusal = np.where((X[:, 2] <= 0) | (depth2 <= 0), "behind", np.where(parallax < MIN_PARALLAX_RAD, "parallax", ""))
    return Triangulated(X, covariances, parallax, refusal)


def in_second_camera(
    R: np.ndarray, L: np.ndarray, points: np.ndarray, covariances: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Points (n, 3) and covariances (n, 3, 3) of the first camera's frame in the second's, X_2 = R X_1
    + L (the cameras of :func:`camera_matrices`)."""
    return points @ R.T + L, np.einsum("ij,njk,lk->nil", R, covariances, R)


def covariance_at(m1: np.ndarray, m2: np.ndarray, X: np.ndarray, *, sigma_px: float = 1.0) -> np.ndarray:
    """The covariances (n, 3, 3) :func:`triangulate` gives points X (n, 3) (the first camera's frame)
    seen where the cameras m1, m2 (3, 4) put them: the pixels' noise at a predicted point instead of
    at the measured pixels. A covariance worked out at the measured pixels follows the measurement's
    own error (a point measured short gets a smaller ellipsoid, its depth variance growing as depth^4
    over the baseline), and a landmark fused from many sightings so weighted drifts short and claims
    too much (docs/ar-slam.md); worked out at a prediction made before the sighting, it does not.
    A point behind either camera has none: NaN."""
    X = np.atleast_2d(X).astype(float)
    pixels, behind = [], np.zeros(len(X), dtype=bool)
    for m in (m1, m2):
        h = X @ m[:, :3].T + m[:, 3]
        behind |= h[:, 2] <= 0.0
        pixels.append(h[:, :2] / np.where(behind, 1.0, h[:, 2])[:, None])
    covariances = triangulate(m1, m2, *pixels, sigma_px=sigma_px).covariances
    covariances[behind] = np.nan
    return covariances


def triangulated_points(m1: np.ndarray, m2: np.ndarray, uv1: np.ndarray, uv2: np.ndarray) -> np.ndarray:
    """The points (n, 3) of :func:`triangulate` alone (the same values), without their covariances,
    parallax or refusals: what a finite difference of the cameras needs."""
    return _least_squares(m1, m2, uv1, uv2)[3]


def _least_squares(
    m1: np.ndarray, m2: np.ndarray, uv1: np.ndarray, uv2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The four linear equations A (n, 4, 3), b (n, 4) of each point, A^T A (n, 3, 3) and their
    least-squares solution X (n, 3)."""
    uv1, uv2 = np.atleast_2d(uv1).astype(float), np.atleast_2d(uv2).astype(float)
    A, b = linear_system(m1, m2, uv1, uv2)
    AtA = np.einsum("nki,nkj->nij", A, A)
    X = np.linalg.solve(AtA, np.einsum("nki,nk->ni", A, b)[..., None])[..., 0]
    return A, b, AtA, X


def _parallax(m1: np.ndarray, m2: np.ndarray, X: np.ndarray) -> np.ndarray:
    """The angle (n,) between the two lines of sight to each point, from the cameras' centres."""
    rays = [X - _centre(m) for m in (m1, m2)]
    cos = np.einsum("ni,ni->n", *rays) / np.maximum(
        np.linalg.norm(rays[0], axis=1) * np.linalg.norm(rays[1], axis=1), 1e-300
    )
    return np.arccos(np.clip(cos, -1.0, 1.0))


def _centre(m: np.ndarray) -> np.ndarray:
    """The centre (3,) of a finite camera m = K [R | L]: -M^-1 m_4."""
    return -np.linalg.solve(m[:, :3], m[:, 3])
