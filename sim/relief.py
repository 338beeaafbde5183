"""Terrain with relief for a 3-D camera (AR-EKF-SLAM paper: a UAV over hills and buildings): a height
field over the procedural ground texture (sim.terrain), both images on one grid. Pure: an explicit
seeded generator.

World frame as sim.terrain's: x east, y north, z up, metres; the grid's centre is the origin. Hills
are Gaussian bumps; buildings are blocks whose walls are smoothed over ``wall_m`` (so that a ray's
crossing with the ground is well defined); the texture's own building and road patterns stay flat.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sim.terrain import procedural_terrain

ROW = 1024  # points per row of the maps cv2.remap is handed


def rolling_hills(xy: np.ndarray) -> np.ndarray:
    """An analytic relief (m) at world points (..., 2) m: rolling hills of up to 9 m (the 3-D
    AR-EKF-SLAM flights', experiments.ar_slam3d and sim.sensor_models.camera3d)."""
    return 6.0 * np.sin(xy[..., 0] / 60.0) * np.cos(xy[..., 1] / 45.0) + 3.0 * np.sin(xy[..., 0] / 23.0 + 1.0)


@dataclass(frozen=True)
class Relief:
    """The ground texture (H, W) uint8 and its height (H, W) float32 [m], ``metres_per_pixel`` apart."""

    texture: np.ndarray
    height_m: np.ndarray
    metres_per_pixel: float

    def to_pixel(self, xy_m: np.ndarray) -> np.ndarray:
        """World points (..., 2) [m] -> grid (col, row) [px], continuous."""
        h, w = self.height_m.shape
        xy = np.asarray(xy_m, dtype=float)
        return np.stack([w / 2 + xy[..., 0] / self.metres_per_pixel, h / 2 - xy[..., 1] / self.metres_per_pixel], -1)

    def height_at(self, xy_m: np.ndarray) -> np.ndarray:
        """Bilinear height (...) [m] at world points (..., 2); outside the grid, the edge's."""
        return sample(self.height_m, self.to_pixel(xy_m))

    def texture_at(self, xy_m: np.ndarray) -> np.ndarray:
        """Bilinear grey level (...) float32 at world points (..., 2); outside the grid, black."""
        return sample(self.texture.astype(np.float32), self.to_pixel(xy_m), border=cv2.BORDER_CONSTANT)


def sample(image: np.ndarray, pixels: np.ndarray, border: int = cv2.BORDER_REPLICATE) -> np.ndarray:
    """``image`` (H, W) float32 at continuous (col, row) ``pixels`` (..., 2), bilinear (cv2.remap)."""
    shape = pixels.shape[:-1]
    flat = pixels.reshape(-1, 2).astype(np.float32)
    n = len(flat)
    grid = np.zeros((-(-n // ROW), ROW, 2), np.float32)  # remap's maps stay under 32767 a side
    grid.reshape(-1, 2)[:n] = flat
    out = cv2.remap(image, grid[..., 0], grid[..., 1], cv2.INTER_LINEAR, borderMode=border, borderValue=0)
    return out.reshape(-1)[:n].reshape(shape)


def relief_terrain(
    rng: np.random.Generator,
    *,
    size_px: int = 2048,
    metres_per_pixel: float = 0.1,
    hills: int = 12,
    hill_height_m: float = 8.0,
    buildings: int = 40,
    building_height_m: float = 10.0,
    wall_m: float = 0.5,
) -> Relief:
    """The procedural ground with ``hills`` Gaussian hills (up to ``hill_height_m``, 10-40 m wide) and
    ``buildings`` blocks (6-20 m a side, up to ``building_height_m`` high)."""
    texture = procedural_terrain(rng, size_px=size_px, metres_per_pixel=metres_per_pixel).image
    span = size_px * metres_per_pixel
    axis = (np.arange(size_px) - size_px / 2) * metres_per_pixel
    x, y = np.meshgrid(axis, -axis)
    height = np.zeros((size_px, size_px), np.float32)
    for _ in range(hills):
        cx, cy = rng.uniform(-span / 2, span / 2, 2)
        width = rng.uniform(10.0, 40.0)
        height += (
            rng.uniform(0.3, 1.0) * hill_height_m * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * width**2))
        ).astype(np.float32)
    blocks = np.zeros_like(height)
    for _ in range(buildings):
        centre = tuple(float(v) for v in rng.uniform(0, size_px, 2))
        sides = tuple(float(v) for v in rng.uniform(6.0, 20.0, 2) / metres_per_pixel)
        corners = cv2.boxPoints((centre, sides, float(rng.uniform(0, 90)))).astype(np.int32)
        cv2.fillConvexPoly(blocks, corners, float(rng.uniform(0.3, 1.0) * building_height_m))
    blocks = cv2.GaussianBlur(blocks, (0, 0), wall_m / metres_per_pixel)
    return Relief(texture, height + blocks, metres_per_pixel)
