"""Corner matching by normalised cross-correlation (the AR-EKF-SLAM paper's NCC), then RANSAC on the
fundamental matrix (vehicle.vision.two_view). Pure; an explicit seeded generator.

Each corner's (2h + 1)^2 patch is made zero-mean and unit-norm, so the NCC of two corners is the dot
product of their patches, for every pair at once (k1, k2); a pair is kept when each is the other's
best, its NCC at least ``min_ncc``, and (optionally) the corners at most ``max_disparity_px`` apart.
Corners closer than h to the border have no patch and are left out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.vision import two_view


@dataclass(frozen=True)
class NccSpec:
    half: int = 5  # patch half-size (11 x 11)
    min_ncc: float = 0.8
    max_disparity_px: float | None = None
    threshold_px: float = 1.5  # RANSAC: an inlier's distance to its epipolar line
    iterations: int = 200


def patches(image: np.ndarray, points: np.ndarray, half: int) -> tuple[np.ndarray, np.ndarray]:
    """Zero-mean, unit-norm patches (k, (2 half + 1)^2) around integer (col, row) ``points`` (k, 2), and
    the indices (k,) of the points that have one."""
    h, w = image.shape
    p = np.rint(points).astype(int)
    inside = np.flatnonzero((p[:, 0] >= half) & (p[:, 0] < w - half) & (p[:, 1] >= half) & (p[:, 1] < h - half))
    if not len(inside):  # no corner away from the border: no patch (and no reshape of nothing)
        return np.zeros((0, (2 * half + 1) ** 2), np.float32), inside
    d = np.arange(-half, half + 1)
    rows = p[inside, 1][:, None, None] + d[None, :, None]
    cols = p[inside, 0][:, None, None] + d[None, None, :]
    out = image[rows, cols].reshape(len(inside), -1).astype(np.float32)
    out -= out.mean(axis=1, keepdims=True)
    norm = np.linalg.norm(out, axis=1, keepdims=True)
    return out / np.maximum(norm, 1e-6), inside


def match(
    image1: np.ndarray, points1: np.ndarray, image2: np.ndarray, points2: np.ndarray, spec: NccSpec = NccSpec()
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mutual best NCC matches: indices (m,) into points1 and points2, and their NCC (m,)."""
    a, ia = patches(image1, points1, spec.half)
    b, ib = patches(image2, points2, spec.half)
    if not len(a) or not len(b):
        return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
    score = a @ b.T
    if spec.max_disparity_px is not None:
        far = np.linalg.norm(points1[ia][:, None, :] - points2[ib][None, :, :], axis=-1) > spec.max_disparity_px
        score[far] = -1.0
    best_b, best_a = score.argmax(axis=1), score.argmax(axis=0)
    keep = np.flatnonzero((best_a[best_b] == np.arange(len(a))) & (score[np.arange(len(a)), best_b] >= spec.min_ncc))
    return ia[keep], ib[best_b[keep]], score[keep, best_b[keep]]


def matched_geometry(
    image1: np.ndarray,
    points1: np.ndarray,
    image2: np.ndarray,
    points2: np.ndarray,
    rng: np.random.Generator,
    spec: NccSpec = NccSpec(),
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """NCC matches kept by RANSAC on F: (F (3, 3), pixels in frame 1 (m, 2), in frame 2 (m, 2)); None
    when fewer than 8 matches or no F fits."""
    i1, i2, _ = match(image1, points1, image2, points2, spec)
    p1, p2 = points1[i1], points2[i2]
    fitted = fundamental(p1, p2, rng, spec)
    if fitted is None:
        return None
    F, inliers = fitted
    return F, p1[inliers], p2[inliers]


def fundamental(
    p1: np.ndarray, p2: np.ndarray, rng: np.random.Generator, spec: NccSpec = NccSpec()
) -> tuple[np.ndarray, np.ndarray] | None:
    """RANSAC on F over matched pixels p1, p2 (m, 2) (``spec``'s threshold and iterations): (F (3, 3),
    inlier mask (m,)), or None when fewer than 8 pairs or no F fits."""
    return two_view.ransac(
        two_view.eight_point,
        two_view.epipolar_distances,
        8,
        p1,
        p2,
        rng,
        threshold=spec.threshold_px**2,
        iterations=spec.iterations,
    )
