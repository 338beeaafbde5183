"""A down-looking camera (vision EKF-SLAM paper): the frame is the window of the terrain image under
the vehicle, rotated to its heading, with pixel noise. Pure.

Frame convention: the vehicle's forward direction points to the top of the frame (row 0), its left
to column 0; the frame's centre pixel is straight below the vehicle. A point ``forward`` m ahead and
``left`` m to the left appears at col = c - left / s, row = c - forward / s, with c = (size - 1) / 2
and s the ground scale [m per pixel].
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from sim.terrain import Terrain


def frame_to_terrain(pose: np.ndarray, terrain: Terrain, size_px: int) -> np.ndarray:
    """The affine map (2, 3) from frame (col, row) to terrain image (col, row) for ``pose`` [x m, y m,
    theta rad] (frame and terrain share the ground scale)."""
    c = (size_px - 1) / 2.0
    cos, sin = math.cos(pose[2]), math.sin(pose[2])
    # frame (u, v) -> body: forward = (c - v) s, left = (c - u) s -> world offset
    # forward (cos, sin) + left (-sin, cos) -> terrain pixels (d col, d row) = (dX / s, -dY / s)
    centre = terrain.to_pixel(np.asarray(pose[:2]))
    A = np.array([[sin, -cos], [cos, sin]])  # [d col, d row] per [u - c, v - c]
    offset = centre - A @ np.array([c, c])
    return np.hstack([A, offset[:, None]])


def camera_frame(
    terrain: Terrain, pose: np.ndarray, rng: np.random.Generator, *, size_px: int = 80, noise_sigma: float = 2.0
) -> np.ndarray:
    """The (size_px, size_px) uint8 frame under ``pose`` with Gaussian pixel noise of ``noise_sigma``
    grey levels; outside the terrain the ground is black."""
    M = frame_to_terrain(pose, terrain, size_px)
    frame = cv2.warpAffine(
        terrain.image,
        M,
        (size_px, size_px),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    noisy = frame.astype(np.float32) + rng.normal(scale=noise_sigma, size=frame.shape).astype(np.float32)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8)
