"""The pinhole camera over relief (sim.pinhole, sim.relief): each pixel's depth puts its point on the
ground and projects back onto the pixel; over flat ground the depth is the geometry's; above the
horizon the sky."""

from __future__ import annotations

import numpy as np
import pytest

from bus.sensors.camera3d import look
from sim.pinhole import Pinhole, render
from sim.relief import relief_terrain


def points_of(camera: Pinhole, C: np.ndarray, R: np.ndarray, depth: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    rays = np.column_stack([pixels, np.ones(len(pixels))]) @ np.linalg.inv(camera.K).T @ R.T
    return C + depth[pixels[:, 1], pixels[:, 0]][:, None] * rays


def test_flat_ground_is_seen_at_the_geometry_s_depth():
    relief = relief_terrain(np.random.default_rng(0), size_px=1024, hills=0, buildings=0)
    camera = Pinhole.paper(0.25)
    pitch, altitude = np.deg2rad(40.0), 15.0
    frame, depth = render(relief, camera, np.array([0.0, 0.0, altitude]), look(0.2, pitch), np.random.default_rng(1))
    cx, cy = (round(v) for v in camera.K[:2, 2])
    assert depth[cy, cx] == pytest.approx(altitude / np.sin(pitch), rel=2e-3)
    assert frame.shape == (120, 160) and frame.dtype == np.uint8


def test_every_pixel_s_point_lies_on_the_relief_and_projects_back():
    rng = np.random.default_rng(2)
    relief = relief_terrain(rng, size_px=1024)
    camera = Pinhole.paper(0.25)
    C, R = np.array([5.0, -3.0, 25.0]), look(1.0, np.deg2rad(50.0))
    _, depth = render(relief, camera, C, R, rng)
    width, height = camera.size
    pixels = np.column_stack([rng.integers(0, width, 200), rng.integers(0, height, 200)])
    pixels = pixels[np.isfinite(depth[pixels[:, 1], pixels[:, 0]])]
    X = points_of(camera, C, R, depth, pixels)
    assert np.abs(X[:, 2] - relief.height_at(X[:, :2])).max() < 0.02
    back, _ = camera.project(R, C, X)
    np.testing.assert_allclose(back, pixels, atol=1e-6)
    assert np.ptp(relief.height_m) > 3.0  # there is relief to see


def test_above_the_horizon_is_sky():
    relief = relief_terrain(np.random.default_rng(3), size_px=512, hills=0, buildings=0)
    camera = Pinhole.paper(0.25)
    frame, depth = render(
        relief, camera, np.array([0.0, 0.0, 10.0]), look(0.0, np.deg2rad(2.0)), np.random.default_rng(4)
    )
    assert np.isinf(depth[0]).all() and np.isfinite(depth[-1]).all()
