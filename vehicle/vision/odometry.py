"""Monocular visual odometry (AR-EKF-SLAM paper, visual odometry section): the motion between two
consecutive camera frames, metric from the known altitude. Pure; an explicit seeded generator.

Two paths, as the scene demands (vehicle.vision.two_view chooses by ORB-SLAM's score ratio):
- ``frame_motion``: the down-looking camera over flat ground (our world's camera): every point lies
  on one plane parallel to the image, so the homography is a 2-D rigid motion of the ground in the
  body frame, fitted by RANSAC over two-point samples and least squares on the inliers; its
  covariance is the fit's, sigma^2 (J^T J)^-1 with sigma from the residuals.
- ``camera_motion``: a pinhole camera over any scene: the homography (decomposed with the ground's
  normal known) or the normalised 8-point F (E = K^T F K, SVD into R, t, cheirality check,
  triangulation), the translation scaled by the altitude (the scene's median depth).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vehicle.vision import two_view
from vehicle.vision.features import Features


@dataclass(frozen=True)
class VoSpec:
    ratio: float = 0.75  # Lowe's ratio test: best descriptor distance under this share of the second
    min_inliers: int = 8
    threshold_px: float = 1.5  # a RANSAC inlier's residual, pixels
    iterations: int = 60
    sigma_floor_px: float = 0.1  # the residual spread is never trusted below this
    unknown_speed_mps: float = 10.0  # sigma of the speed before the first motion is measured
    unseen_accel_mps2: float = 1.0  # how fast the speed may change while no motion is found


@dataclass(frozen=True)
class FrameMotion:
    """The second frame's body pose in the first's: [forward m, left m, yaw rad] (3,), its covariance
    (3, 3), and how many matches agreed."""

    delta: np.ndarray
    covariance: np.ndarray
    inliers: int


@dataclass(frozen=True)
class NoMotion:
    """Why a frame pair gave no motion (counted and reported by the vehicle)."""

    reason: str


def match(first: Features, second: Features, ratio: float) -> tuple[np.ndarray, np.ndarray]:
    """Indices (m,), (m,) of keypoints of ``first`` and ``second`` matched by descriptor with Lowe's
    ratio test, each keypoint of ``second`` used at most once."""
    if len(first.points_px) < 2 or len(second.points_px) < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    norm = cv2.NORM_HAMMING if first.descriptors.dtype == np.uint8 else cv2.NORM_L2
    pairs = cv2.BFMatcher(norm).knnMatch(first.descriptors, second.descriptors, k=2)
    good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < ratio * p[1].distance]
    good.sort(key=lambda d: d.distance)
    taken, i1, i2 = set(), [], []
    for d in good:
        if d.trainIdx not in taken:
            taken.add(d.trainIdx)
            i1.append(d.queryIdx)
            i2.append(d.trainIdx)
    return np.asarray(i1, np.int64), np.asarray(i2, np.int64)


def body_points(points_px: np.ndarray, size_px: int, metres_per_pixel: float) -> np.ndarray:
    """Pixels (k, 2) as (col, row) -> ground points [forward m, left m] (k, 2) in the body frame."""
    c = (size_px - 1) / 2.0
    return np.stack([(c - points_px[:, 1]), (c - points_px[:, 0])], axis=1) * metres_per_pixel


def rigid_fit(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """Least-squares 2-D rotation angle and translation (2,) with b ~ R(angle) a + t (a, b: (n, 2))."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    da, db = a - ca, b - cb
    angle = float(np.arctan2(np.sum(da[:, 0] * db[:, 1] - da[:, 1] * db[:, 0]), np.sum(da * db)))
    return angle, cb - rotation(angle) @ ca


def rotation(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def rigid_residuals(angle: float, t: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """b - (R a + t), (n, 2)."""
    return b - a @ rotation(angle).T - t


def rigid_ransac(
    a: np.ndarray, b: np.ndarray, rng: np.random.Generator, *, threshold: float, iterations: int
) -> np.ndarray:
    """Inlier mask (n,) of the two-point rigid motion agreed by most pairs (residual under
    ``threshold``), all ``iterations`` samples drawn and scored at once."""
    pick = rng.integers(0, len(a), size=(iterations, 2))
    a0, a1, b0, b1 = a[pick[:, 0]], a[pick[:, 1]], b[pick[:, 0]], b[pick[:, 1]]
    da, db = a1 - a0, b1 - b0
    valid = np.linalg.norm(da, axis=1) > 1e-9
    angle = np.arctan2(da[:, 0] * db[:, 1] - da[:, 1] * db[:, 0], np.sum(da * db, axis=1))
    c, s = np.cos(angle), np.sin(angle)
    mid_a, mid_b = (a0 + a1) / 2, (b0 + b1) / 2
    t = mid_b - np.stack([c * mid_a[:, 0] - s * mid_a[:, 1], s * mid_a[:, 0] + c * mid_a[:, 1]], axis=1)
    moved = (
        np.stack(  # (iterations, n, 2): R a + t for every sample
            [c[:, None] * a[:, 0] - s[:, None] * a[:, 1], s[:, None] * a[:, 0] + c[:, None] * a[:, 1]], axis=2
        )
        + t[:, None, :]
    )
    inliers = (np.linalg.norm(b[None] - moved, axis=2) < threshold) & valid[:, None]
    return inliers[int(np.argmax(inliers.sum(axis=1)))]


def rigid_covariance(angle: float, a: np.ndarray, residuals: np.ndarray, sigma_floor: float) -> np.ndarray:
    """Covariance (3, 3) of [tx, ty, angle] from the fit: sigma^2 (J^T J)^-1, sigma^2 the residuals'
    variance per coordinate (2n - 3 degrees of freedom), floored at ``sigma_floor``^2."""
    n = len(a)
    sigma2 = max(float(np.sum(residuals**2)) / max(2 * n - 3, 1), sigma_floor**2)
    c, s = np.cos(angle), np.sin(angle)
    J = np.zeros((2 * n, 3))
    J[0::2, 0] = J[1::2, 1] = 1.0
    J[0::2, 2] = -s * a[:, 0] - c * a[:, 1]
    J[1::2, 2] = c * a[:, 0] - s * a[:, 1]
    return sigma2 * np.linalg.inv(J.T @ J)


def frame_motion(
    first: Features,
    second: Features,
    size_px: int,
    metres_per_pixel: float,
    rng: np.random.Generator,
    spec: VoSpec = VoSpec(),
) -> FrameMotion | NoMotion:
    """The motion from the first frame to the second (module docstring). A ground point at body
    coordinates b2 in the second frame is at b1 = R(dyaw) b2 + d in the first, d = [forward, left]."""
    if len(first.points_px) == 0 or len(second.points_px) == 0:
        return NoMotion("a frame without features")
    i1, i2 = match(first, second, spec.ratio)
    if len(i1) < spec.min_inliers:
        return NoMotion(f"{len(i1)} matches, fewer than {spec.min_inliers}")
    b1 = body_points(first.points_px[i1], size_px, metres_per_pixel)
    b2 = body_points(second.points_px[i2], size_px, metres_per_pixel)
    inliers = rigid_ransac(b2, b1, rng, threshold=spec.threshold_px * metres_per_pixel, iterations=spec.iterations)
    if inliers.sum() < spec.min_inliers:
        return NoMotion(f"a degenerate fit: {int(inliers.sum())} of {len(i1)} matches agree")
    a, b = b2[inliers], b1[inliers]
    if np.ptp(a, axis=0).max() < 2 * metres_per_pixel:
        return NoMotion("a degenerate fit: the agreeing matches are one spot")
    angle, t = rigid_fit(a, b)
    covariance = rigid_covariance(angle, a, rigid_residuals(angle, t, a, b), spec.sigma_floor_px * metres_per_pixel)
    return FrameMotion(np.array([t[0], t[1], angle]), covariance, int(inliers.sum()))


@dataclass(frozen=True)
class CameraMotion:
    """Camera 2 in camera 1 (X2 = R X1 + t, t in metres), the model used and ORB-SLAM's ratio R_H."""

    R: np.ndarray
    t: np.ndarray
    model: str
    ratio: float


def camera_motion(
    p1: np.ndarray,
    p2: np.ndarray,
    K: np.ndarray,
    altitude_m: float,
    rng: np.random.Generator,
    *,
    sigma_px: float = 1.0,
) -> CameraMotion | NoMotion:
    """Motion of a pinhole camera (intrinsics K (3, 3)) looking down from ``altitude_m`` between two
    views of matched pixels p1, p2 (n, 2) (module docstring)."""
    if len(p1) < 8:
        return NoMotion(f"{len(p1)} matches, fewer than 8")
    choice = two_view.select_model(p1, p2, rng, sigma_px=sigma_px)
    if choice is None:
        return NoMotion("a degenerate fit: neither a homography nor a fundamental matrix")
    if choice.model == "homography":
        count, Rs, ts, normals = cv2.decomposeHomographyMat(choice.H, K)
        # the ground faces the camera: the decomposition whose plane normal is closest to the optical axis
        k = int(np.argmax([abs(float(normals[i][2, 0])) for i in range(count)]))
        return CameraMotion(Rs[k], ts[k].ravel() * altitude_m, "homography", choice.ratio)
    pose = two_view.relative_pose(choice.F, K, p1, p2)
    depths = pose.points[:, 2][pose.points[:, 2] > 0]
    if len(depths) < 8:
        return NoMotion("a degenerate fit: too few points in front of both cameras")
    return CameraMotion(pose.R, pose.t * altitude_m / float(np.median(depths)), "fundamental", choice.ratio)
