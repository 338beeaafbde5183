"""Vision front end (vision EKF-SLAM paper): keypoints and descriptors with OpenCV (SIFT, or ORB),
the paper's thinning (the frame split into 30 x 30 px cells, the strongest keypoint of each kept),
and pixel offsets turned into range and bearing in the body frame. Pure.

Frame convention (sim/camera.py): forward is up (row 0), left is column 0, the centre pixel is below
the vehicle; ``metres_per_pixel`` is the ground scale the camera reports with every frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Features:
    """Keypoints of one frame: pixel positions (k, 2) as (col, row), detector responses (k,) and
    descriptors (k, d) (float32 for SIFT, uint8 for ORB)."""

    points_px: np.ndarray
    responses: np.ndarray
    descriptors: np.ndarray


def make_detector(kind: str = "sift"):
    """An OpenCV feature detector: ``sift`` (the paper's) or ``orb``."""
    if kind == "sift":
        return cv2.SIFT_create()
    if kind == "orb":
        return cv2.ORB_create(nfeatures=500, edgeThreshold=8, patchSize=15)
    raise ValueError(f"unknown feature detector {kind!r}: use sift or orb")


def detect(frame: np.ndarray, detector) -> Features:
    """Keypoints and descriptors of a grey uint8 frame (H, W)."""
    keypoints, descriptors = detector.detectAndCompute(frame, None)
    if not keypoints or descriptors is None:
        return Features(np.zeros((0, 2)), np.zeros(0), np.zeros((0, detector.descriptorSize()), np.float32))
    points = np.array([kp.pt for kp in keypoints], dtype=float)
    responses = np.array([kp.response for kp in keypoints], dtype=float)
    return Features(points, responses, descriptors)


def thin(features: Features, cell_px: int = 30) -> Features:
    """The strongest keypoint of each ``cell_px`` x ``cell_px`` cell (paper: ~9000 -> ~900)."""
    keep = thin_indices(features.points_px, features.responses, cell_px)
    return Features(features.points_px[keep], features.responses[keep], features.descriptors[keep])


def thin_indices(points_px: np.ndarray, responses: np.ndarray, cell_px: int = 30) -> np.ndarray:
    """Indices (sorted) of the strongest of ``points_px`` (k, 2) in each ``cell_px`` cell."""
    if len(responses) == 0:
        return np.zeros(0, dtype=np.int64)
    cells = (points_px // cell_px).astype(np.int64)
    key = cells[:, 0] * 1_000_003 + cells[:, 1]
    order = np.lexsort((-responses, key))  # by cell, strongest first within a cell
    first = np.ones(len(order), dtype=bool)
    first[1:] = key[order][1:] != key[order][:-1]
    return np.sort(order[first])


def garbage_reason(pixels: object) -> str | None:
    """Why a camera frame cannot be used (None: it can): not a square grey uint8 image, empty,
    all black, or without texture (grey-level spread under 2)."""
    if (
        not isinstance(pixels, np.ndarray)
        or pixels.dtype != np.uint8
        or pixels.ndim != 2
        or pixels.shape[0] != pixels.shape[1]
    ):
        return "not a square grey uint8 frame"
    if pixels.size == 0:
        return "empty frame"
    if not pixels.any():
        return "all black"
    if float(pixels.std()) < 2.0:
        return "no texture (uniform grey)"
    return None


def range_bearing(points_px: np.ndarray, size_px: int, metres_per_pixel: float) -> np.ndarray:
    """Pixel positions (k, 2) as (col, row) -> [range m, bearing rad] (k, 2) in the body frame
    (bearing counter-clockwise from forward)."""
    c = (size_px - 1) / 2.0
    forward = (c - points_px[:, 1]) * metres_per_pixel
    left = (c - points_px[:, 0]) * metres_per_pixel
    return np.stack([np.hypot(forward, left), np.arctan2(left, forward)], axis=1)


def pixel_noise_to_range_bearing(
    points_px: np.ndarray, size_px: int, metres_per_pixel: float, sigma_px: float
) -> np.ndarray:
    """Covariances (k, 2, 2) of [range, bearing] for an isotropic keypoint error of ``sigma_px``:
    sigma_r = sigma_px s, sigma_b = sigma_px s / r (r floored at one pixel)."""
    rb = range_bearing(points_px, size_px, metres_per_pixel)
    sigma_m = sigma_px * metres_per_pixel
    r = np.maximum(rb[:, 0], metres_per_pixel)
    out = np.zeros((len(rb), 2, 2))
    out[:, 0, 0] = sigma_m**2
    out[:, 1, 1] = (sigma_m / r) ** 2
    return out


def body_to_world(pose: np.ndarray, rb: np.ndarray) -> np.ndarray:
    """Where [range, bearing] (k, 2) seen from ``pose`` [x, y, theta] lie in the world (k, 2)."""
    a = rb[:, 1] + pose[2]
    return np.stack([pose[0] + rb[:, 0] * np.cos(a), pose[1] + rb[:, 0] * np.sin(a)], axis=1)
