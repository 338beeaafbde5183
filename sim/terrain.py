"""The aerial image the camera vehicles fly over (vision EKF-SLAM paper: a window of a large aerial
image). By default a procedural, deterministic terrain: fields of different textures, roads,
buildings with shadows, trees, and grain at several scales, so that SIFT finds thousands of
keypoints; or any PNG/JPEG orthophoto. Pure: an explicit seeded generator, no files written.

World frame: x east, y north, metres; the image's centre is the world origin, rows grow southwards.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from bus.config import SwarmConfig
from bus.errors import ConfigError
from bus.pads import start_pads


@dataclass(frozen=True)
class Terrain:
    """A grey-level ground image (H, W) uint8 and its scale [m per pixel]."""

    image: np.ndarray
    metres_per_pixel: float

    @property
    def size_m(self) -> tuple[float, float]:
        """(width, height) in metres."""
        h, w = self.image.shape
        return w * self.metres_per_pixel, h * self.metres_per_pixel

    def to_pixel(self, xy_m: np.ndarray) -> np.ndarray:
        """World points (..., 2) [m] -> image (col, row) [px] (continuous, pixel centres at .5)."""
        h, w = self.image.shape
        xy = np.asarray(xy_m, dtype=float)
        return np.stack(
            [w / 2 + xy[..., 0] / self.metres_per_pixel, h / 2 - xy[..., 1] / self.metres_per_pixel], axis=-1
        )


def load_terrain(path: Path, metres_per_pixel: float) -> Terrain:
    """An orthophoto from ``path`` (PNG/JPEG, read as grey); a one-line ConfigError if unreadable."""
    if not Path(path).is_file():
        raise ConfigError(f"terrain image {path} does not exist")
    image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    if image is None or min(image.shape) < 100:
        raise ConfigError(f"terrain image {path} is not a readable PNG/JPEG of at least 100 x 100 px")
    return Terrain(image, metres_per_pixel)


def _grain(rng: np.random.Generator, shape: tuple[int, int], cell_px: int) -> np.ndarray:
    """Smooth noise (H, W) in [-1, 1] with features about ``cell_px`` pixels large."""
    h, w = shape
    small = rng.uniform(-1.0, 1.0, size=(h // cell_px + 2, w // cell_px + 2)).astype(np.float32)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_CUBIC).clip(-1.0, 1.0)


def procedural_terrain(rng: np.random.Generator, *, size_px: int = 2048, metres_per_pixel: float = 0.1) -> Terrain:
    """Fields, roads, buildings, trees and grain at several scales on ``size_px`` x ``size_px`` pixels."""
    shape = (size_px, size_px)
    base = 110.0 + 25.0 * _grain(rng, shape, 256) + 12.0 * _grain(rng, shape, 48) + 6.0 * _grain(rng, shape, 8)
    image = base.astype(np.float32)
    fields = np.zeros(shape, np.float32)
    for _ in range(size_px // 40):  # fields: convex patches with a brightness and a furrow texture
        centre = rng.uniform(0, size_px, size=2)
        corners = (centre + rng.normal(scale=size_px / 14, size=(6, 2))).astype(np.int32)
        mask = np.zeros(shape, np.uint8)
        cv2.fillConvexPoly(mask, cv2.convexHull(corners), 1)
        angle = rng.uniform(0, np.pi)
        rows, cols = np.nonzero(mask)
        furrows = 10.0 * np.sin((cols * np.cos(angle) + rows * np.sin(angle)) * rng.uniform(0.3, 0.9))
        fields[rows, cols] = rng.uniform(-40, 40) + furrows
    image += fields
    for _ in range(size_px // 150):  # roads: bright polylines with dark edges
        points = np.cumsum(rng.normal(scale=size_px / 8, size=(5, 2)), axis=0) + rng.uniform(0, size_px, size=2)
        points = points.astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(image, [points], False, 60.0, thickness=int(rng.integers(14, 22)))
        cv2.polylines(image, [points], False, 200.0, thickness=int(rng.integers(8, 12)))
    for _ in range(size_px // 6):  # buildings: rectangles with a roof tone and a shadow
        x, y = rng.uniform(0, size_px, size=2)
        w, h = rng.uniform(8, 40, size=2)
        box = ((float(x), float(y)), (float(w), float(h)), float(rng.uniform(0, 90)))
        corners = cv2.boxPoints(box).astype(np.int32)
        cv2.fillConvexPoly(image, corners + 4, 30.0)
        cv2.fillConvexPoly(image, corners, float(rng.uniform(150, 250)))
    for _ in range(size_px * 2):  # trees: dark blobs
        centre = tuple(int(v) for v in rng.uniform(0, size_px, size=2))
        cv2.circle(image, centre, int(rng.integers(2, 7)), float(rng.uniform(20, 70)), -1)
    return Terrain(np.clip(image, 0, 255).astype(np.uint8), metres_per_pixel)


def repetitive_terrain(
    rng: np.random.Generator, *, size_px: int, period_px: int, metres_per_pixel: float = 0.1
) -> Terrain:
    """One ``period_px`` square tile of the procedural terrain repeated over ``size_px`` x ``size_px``
    (tiles, paving, a planted orchard): every keypoint has exact look-alikes a period away."""
    source = procedural_terrain(rng, size_px=max(256, 4 * period_px), metres_per_pixel=metres_per_pixel).image
    start = (source.shape[0] - period_px) // 2
    tile = source[start : start + period_px, start : start + period_px]
    reps = -(-size_px // period_px)
    return Terrain(np.ascontiguousarray(np.tile(tile, (reps, reps))[:size_px, :size_px]), metres_per_pixel)


def make_terrain(config: SwarmConfig) -> Terrain:
    """The ground the cameras see: ``world.terrain`` (an orthophoto) or a procedural one from the
    world's seed (ConfigError, one line, for an unreadable file). OpenCV and the terrain are loaded
    only for a camera swarm (sim.world imports this module then)."""
    wc = config.world
    if wc.terrain:
        return load_terrain(wc.terrain, wc.terrain_metres_per_pixel)
    size_px = wc.terrain_size_px or terrain_size_for(config)
    rng = np.random.default_rng([wc.seed, 0, 7])
    if wc.terrain_period_px:
        return repetitive_terrain(
            rng, size_px=size_px, period_px=wc.terrain_period_px, metres_per_pixel=wc.terrain_metres_per_pixel
        )
    return procedural_terrain(rng, size_px=size_px, metres_per_pixel=wc.terrain_metres_per_pixel)


def terrain_size_for(config: SwarmConfig, margin_m: float = 20.0) -> int:
    """Side [px] of a terrain centred on the origin that holds every start pad, the trajectory
    around it (``radius_m``) and a camera footprint's margin: at least 2048, at most 8192."""
    wc = config.world
    reach_m = float(np.max(np.abs(start_pads(wc.vehicles, wc.spacing_m)))) + wc.radius_m + margin_m
    return int(min(8192, max(2048, 2 * np.ceil(reach_m / wc.terrain_metres_per_pixel))))
