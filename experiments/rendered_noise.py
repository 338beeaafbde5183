"""What the rendered chain's front end should tell the back end, measured where the truth is known: on
rendered flights of their own (experiments.ar_slam3d's FIT_SEEDS, never scored), each pair of frames
``baseline_frames`` apart whose two-view geometry holds (rotation given, ``relative``), with the corners
followed from frame to frame (vehicle.vision.corner_tracks).

- The pixels' noise: each pair's pixel in the newer frame against where the ground seen at its pixel
  of the older frame (the rendered depth, interpolated) projects. The triangulation takes both pixels
  of a pair as noisy alike and independently (sigma per coordinate), so the pair's difference has
  twice that variance: the sigma told is the pairs' RMS error per coordinate over sqrt(2).
- The fitted direction of travel's error, per axis across it (``across``): one per pair of frames,
  shared by every point the pair triangulates (measured; told to the back end as an error the frame's
  points share, it changed nothing: docs/decisions/ar-slam3d-rendered.md).

And how well-posed the paper's visual odometry is on such frames (``two_view_errors``): exact
correspondences of the rendered ground with noise added.

Pure; seeded.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from experiments.ar_slam3d import FIT_SEEDS
from experiments.ar_slam3d_rendered import RenderedFlight, flight
from experiments.rendered_front_end import relative, rotation_angle_rad
from sim.pinhole import render
from vehicle.vision import susan
from vehicle.vision.corner_tracks import CornerTracks


def tracked_pixel_sigma(seeds: Sequence[int] = FIT_SEEDS[:2], frames: int = 100) -> float:
    """The pixel noise per coordinate (px) to tell the triangulation for followed corners, from
    ``frames`` frames of each flight ``seeds`` (module docstring)."""
    pixels = np.concatenate([flight_errors(seed, frames)[0] for seed in seeds])
    return float(np.sqrt(np.mean((pixels - pixels.mean(axis=0)) ** 2) / 2.0))


def flight_errors(seed: int, frames: int, baseline_frames: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Over ``frames`` frames of flight ``seed``: each kept pair's pixel error (m, 2) px (its pixel in the
    newer frame less the true projection there of the ground at its pixel in the older frame), and
    each pair of frames' direction error (f, 2) rad (the fitted unit direction less the true, along
    the two axes across the true)."""
    path = flight(seed, frames + 1)
    rng = np.random.default_rng([seed, 5])
    tracks, depths, pixel_errors, direction_errors = CornerTracks(), {}, [], []
    for k in range(frames + 1):
        image, depths[k] = render(path.relief, path.camera, path.positions[k], path.rotations[k], rng)
        depths.pop(k - baseline_frames - 1, None)
        tracks.step(k, image, susan.corners(image)[0].astype(float))
        j = k - baseline_frames
        if j < 0:
            continue
        p1, p2, _ = tracks.pairs(j, k)
        fitted = relative(path.camera, p1, p2, rng, path.rotations[k].T @ path.rotations[j])
        if fitted is None:
            continue
        pose, inliers = fitted
        error = p2[inliers] - projected(path, depths[j], j, k, p1[inliers])
        pixel_errors.append(error[np.isfinite(error).all(axis=1)])
        truth = path.rotations[k].T @ (path.positions[j] - path.positions[k])  # X_k = R X_j + t: t's direction
        truth /= np.linalg.norm(truth)
        direction_errors.append(across(truth) @ (pose.t / np.linalg.norm(pose.t) - truth))
    return np.concatenate(pixel_errors), np.array(direction_errors).reshape(-1, 2)


def across(t: np.ndarray) -> np.ndarray:
    """Two unit axes (2, 3) perpendicular to the unit direction ``t`` (3,) and to each other."""
    first = np.cross(t, np.eye(3)[int(np.argmin(np.abs(t)))])
    first /= np.linalg.norm(first)
    return np.array([first, np.cross(t, first)])


def two_view_errors(
    seed: int, sigma_px: float, pairs: int = 11, points: int = 40, draws: int = 3, baseline_frames: int = 10
) -> tuple[np.ndarray, np.ndarray]:
    """The paper's visual odometry (RANSAC on F, R and t from E; ``relative`` with no rotation given) on
    exact correspondences with pixel noise ``sigma_px`` added: for ``pairs`` pairs of frames of flight
    ``seed``, ``points`` ground points of a grid each, ``draws`` noise draws each, the relative rotation's
    error (deg) and the direction of travel's (deg), each (n,). How well-posed the two-view geometry is,
    whatever the front end."""
    path = flight(seed, pairs * baseline_frames + baseline_frames + 1)
    rng = np.random.default_rng([seed, 11])
    grid = np.stack(np.meshgrid(np.arange(10, 310, 15.0), np.arange(10, 230, 15.0)), -1).reshape(-1, 2)
    rotation_deg, direction_deg = [], []
    for j in range(baseline_frames, (pairs + 1) * baseline_frames, baseline_frames):
        k = j + baseline_frames
        _, depth = render(path.relief, path.camera, path.positions[j], path.rotations[j], rng)
        seen = projected(path, depth, j, k, grid)
        width, height = path.camera.size
        inside = np.isfinite(seen).all(axis=1) & (seen >= 0).all(axis=1) & (seen[:, 0] < width) & (seen[:, 1] < height)
        chosen = rng.choice(np.flatnonzero(inside), size=min(points, int(inside.sum())), replace=False)
        R_true = path.rotations[k].T @ path.rotations[j]
        t_true = path.rotations[k].T @ (path.positions[j] - path.positions[k])
        for _ in range(draws):
            noisy = [p + rng.normal(0.0, sigma_px, p.shape) for p in (grid[chosen], seen[chosen])]
            fitted = relative(path.camera, *noisy, rng, None)
            if fitted is None:
                continue
            rotation_deg.append(float(np.degrees(rotation_angle_rad(fitted[0].R.T @ R_true))))
            cosine = fitted[0].t @ t_true / np.linalg.norm(fitted[0].t) / np.linalg.norm(t_true)
            direction_deg.append(float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))))
    return np.array(rotation_deg), np.array(direction_deg)


def projected(path: RenderedFlight, depth: np.ndarray, j: int, k: int, pixels: np.ndarray) -> np.ndarray:
    """Where the ground seen at ``pixels`` (m, 2) (col, row) of frame j, its depth map ``depth`` (H, W)
    m along the axis, lies in frame k (m, 2) px."""
    K = path.camera.K
    rays = np.column_stack([pixels, np.ones(len(pixels))]) @ np.linalg.inv(K).T
    X = path.positions[j] + (rays * bilinear(depth, pixels)[:, None]) @ path.rotations[j].T
    uv = (X - path.positions[k]) @ path.rotations[k] @ K.T
    return uv[:, :2] / uv[:, 2:]


def bilinear(image: np.ndarray, pixels: np.ndarray) -> np.ndarray:
    """``image`` (H, W) interpolated at ``pixels`` (m, 2) (col, row), each at least a pixel inside."""
    col, row = pixels[:, 0], pixels[:, 1]
    c0, r0 = np.floor(col).astype(int), np.floor(row).astype(int)
    fc, fr = col - c0, row - r0
    top = image[r0, c0] * (1 - fc) + image[r0, c0 + 1] * fc
    bottom = image[r0 + 1, c0] * (1 - fc) + image[r0 + 1, c0 + 1] * fc
    return top * (1 - fr) + bottom * fr
