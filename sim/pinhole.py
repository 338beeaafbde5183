"""A pinhole camera over terrain with relief (sim.relief): the AR-EKF-SLAM paper's camera, K of 640 x
480 pixels (``scale`` shrinks the frame and K alike: fx, fy, cx, cy times the scale), frames rendered
by casting every pixel's ray onto the height field, with pixel noise. Pure.

Camera frame: x right, y down, z along the optical axis; ``look(yaw, pitch)`` (bus.sensors.camera3d:
the mount the world and the vehicles share) points the axis at heading ``yaw`` (rad from east,
counter-clockwise) and ``pitch`` below the horizon. A ray X(t) = C + t d (d = R_wc K^-1 [u, v, 1],
t the depth along the axis) is marched in ``MARCH_STEPS`` steps from ``near_m`` to ``far_m`` to the
first point below the ground, then bisected ``BISECTIONS`` times; a ray that meets no ground by
``far_m`` sees the sky (grey ``SKY``, depth inf). Rendering returns the depth of every pixel too:
the truth a test or a benchmark projects through.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bus.sensors.camera3d import PAPER_K
from sim.relief import Relief

PAPER_SIZE = (640, 480)
MARCH_STEPS = 48
BISECTIONS = 10
SKY = 200


@dataclass(frozen=True)
class Pinhole:
    """Intrinsics K (3, 3) and the frame's (width, height) in pixels."""

    K: np.ndarray
    size: tuple[int, int]

    @classmethod
    def paper(cls, scale: float = 1.0) -> Pinhole:
        K = PAPER_K.copy()
        K[:2] *= scale
        return cls(K, (round(PAPER_SIZE[0] * scale), round(PAPER_SIZE[1] * scale)))

    def project(self, R_wc: np.ndarray, C: np.ndarray, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World points X (n, 3) -> pixels (n, 2) (col, row) and their depth (n,)."""
        camera = (X - C) @ R_wc  # R_wc^T (X - C), row by row
        pixels = camera @ self.K.T
        return pixels[:, :2] / pixels[:, 2:3], camera[:, 2]

    def in_view(self, uv: np.ndarray, depth: np.ndarray, far_m: float, near_m: float = 0.5) -> np.ndarray:
        """Which projected points (``project``'s pixels (n, 2) and depths (n,)) the frame shows: in
        front between ``near_m`` and ``far_m``, inside the frame (n,) bool."""
        width, height = self.size
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < width) & (uv[:, 1] >= 0) & (uv[:, 1] < height)
        return inside & (depth > near_m) & (depth < far_m)


def render(
    relief: Relief,
    camera: Pinhole,
    C: np.ndarray,
    R_wc: np.ndarray,
    rng: np.random.Generator,
    *,
    noise_sigma: float = 2.0,
    near_m: float = 0.5,
    far_m: float = 200.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The frame (H, W) uint8 seen from centre C (3,) with orientation R_wc, and each pixel's depth
    (H, W) [m along the axis; inf for the sky] (module docstring)."""
    width, height = camera.size
    u, v = np.meshgrid(np.arange(width, dtype=float), np.arange(height, dtype=float))
    rays = np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(camera.K).T @ R_wc.T  # (H, W, 3), unit depth

    def below(t: np.ndarray) -> np.ndarray:
        points = C + t[..., None] * rays
        return points[..., 2] - relief.height_at(points[..., :2])

    steps = near_m * (far_m / near_m) ** np.linspace(0.0, 1.0, MARCH_STEPS)  # finer near the camera
    low = np.full(u.shape, steps[0])
    high = np.full(u.shape, np.inf)
    for previous, t in zip(steps[:-1], steps[1:]):
        crossed = np.isinf(high) & (below(np.full(u.shape, t)) < 0.0)
        low[crossed], high[crossed] = previous, t
    ground = np.isfinite(high)
    for _ in range(BISECTIONS):
        middle = np.where(ground, 0.5 * (low + high), low)
        under = below(middle) < 0.0
        high = np.where(ground & under, middle, high)
        low = np.where(ground & ~under, middle, low)
    depth = np.where(ground, 0.5 * (low + high), np.inf)
    points = C + np.where(ground, depth, 0.0)[..., None] * rays
    grey = np.where(ground, relief.texture_at(points[..., :2]), SKY)
    noisy = grey + rng.normal(0.0, noise_sigma, grey.shape)
    return np.clip(np.rint(noisy), 0, 255).astype(np.uint8), depth
