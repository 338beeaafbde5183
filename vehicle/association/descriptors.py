"""Data association for vision EKF-SLAM: which mapped landmarks a frame can see, and which of its
keypoints are which landmark (descriptor match with Lowe's ratio test; the EKF's Mahalanobis gate
confirms each pair). Pure.
"""

from __future__ import annotations

import cv2
import numpy as np


def in_view(landmarks_xy_m: np.ndarray, pose: np.ndarray, half_extent_m: float) -> np.ndarray:
    """Indices of landmarks (m, 2) [m] inside the square footprint of half side ``half_extent_m``
    [m] around ``pose`` [x, y, theta] (the frame is aligned with the heading)."""
    if len(landmarks_xy_m) == 0:
        return np.zeros(0, dtype=np.int64)
    return np.flatnonzero(np.all(np.abs(to_body(landmarks_xy_m, pose)) <= half_extent_m, axis=1))


def match(
    frame_descriptors: np.ndarray, map_descriptors: np.ndarray, norm: int, ratio: float = 0.8
) -> list[tuple[int, int]]:
    """One-to-one pairs (frame keypoint, map row). Each landmark in view looks for its keypoint in
    the frame and keeps it when the best beats the frame's second best by ``ratio`` (Lowe's test
    among the frame's own keypoints: a landmark mapped twice does not veto itself); a keypoint
    claimed by several landmarks goes to the closest descriptor. Descriptors (k, d), (m, d)."""
    if len(frame_descriptors) == 0 or len(map_descriptors) == 0:
        return []
    matcher = cv2.BFMatcher(norm)
    k = 2 if len(frame_descriptors) > 1 else 1
    best: dict[int, tuple[float, int]] = {}
    for pair in matcher.knnMatch(map_descriptors, frame_descriptors, k=k):
        if not pair or (len(pair) == 2 and pair[0].distance > ratio * pair[1].distance):
            continue
        first = pair[0]
        if first.trainIdx not in best or first.distance < best[first.trainIdx][0]:
            best[first.trainIdx] = (first.distance, first.queryIdx)
    return sorted((keypoint, row) for keypoint, (_, row) in best.items())


def shortlist(
    frame_descriptors: np.ndarray, map_descriptors: np.ndarray, norm: int, size: int
) -> list[tuple[int, int]]:
    """Pairs (frame keypoint, map row): each landmark's ``size`` nearest keypoints by descriptor (the
    candidates a geometric association chooses among; on repetitive ground they include the
    look-alikes). Descriptors (k, d), (m, d)."""
    if len(frame_descriptors) == 0 or len(map_descriptors) == 0:
        return []
    knn = cv2.BFMatcher(norm).knnMatch(map_descriptors, frame_descriptors, k=min(size, len(frame_descriptors)))
    return sorted({(match.trainIdx, match.queryIdx) for matches in knn for match in matches})


def to_body(points_xy_m: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """World points (k, 2) [m] -> [forward, left] (k, 2) [m] in the body frame of ``pose``."""
    d = points_xy_m - pose[:2]
    c, s = np.cos(pose[2]), np.sin(pose[2])
    return np.stack([d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c], axis=1)


def rigidly_consistent(
    predicted_m: np.ndarray, measured_m: np.ndarray, threshold_m: float, min_inliers: int = 3
) -> np.ndarray:
    """Which matches (k,) agree on one rotation + translation between where the map predicts the
    landmarks (k, 2) and where the frame sees them (k, 2), both body frame [m] (RANSAC, OpenCV). A
    pose error moves every correct match alike; a false match does not. Fewer than ``min_inliers``
    agreeing: none is trusted (a consensus of two proves nothing)."""
    k = len(predicted_m)
    if k < min_inliers:
        return np.zeros(k, dtype=bool)
    _, inliers = cv2.estimateAffinePartial2D(
        predicted_m.astype(np.float32),
        measured_m.astype(np.float32),
        method=cv2.RANSAC,
        ransacReprojThreshold=threshold_m,
        maxIters=200,
        confidence=0.99,
        refineIters=0,
    )
    if inliers is None:
        return np.zeros(k, dtype=bool)
    mask = inliers.ravel().astype(bool)
    return mask if mask.sum() >= min_inliers else np.zeros(k, dtype=bool)
