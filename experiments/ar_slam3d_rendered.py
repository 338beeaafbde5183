"""The AR-EKF-SLAM paper's whole 3-D system on rendered frames: the camera of experiments.ar_slam3d
(the paper's K scaled by ``SCALE``, 10 frames a second, 5 m/s, 15 m over the ground, 30 degrees down)
flies circles over terrain with hills and buildings (sim.relief); each frame is rendered by ray
casting (sim.pinhole.render, grey-level noise); the paper's front end finds SUSAN corners
(vehicle.vision.susan), matches them by NCC and keeps what RANSAC on F keeps (vehicle.vision.ncc);
visual odometry takes R from E = K^T F K by cheirality (vehicle.vision.two_view); the matched corners
are triangulated (vehicle.vision.triangulation, the paper's least squares) and fused by the 6 + 3n back
end (vehicle.estimators.ar_slam3d) with nn association: no landmark ids, no projected points. Pure;
seeded.

What is given, as in the paper: the metric length of the baseline between the two frames (VO's
translation has no scale), and the first ``baseline_frames`` frames' rotations (a surveyed start).
``rotation``: "vo" chains each frame's rotation from the frame ``baseline_frames`` before by VO's R (the
paper), "given" hands the back end the true rotation (the front end's share of the error apart).
The altitude follows the relief smoothed over ``FOLLOW_M`` (a UAV does not jump each wall); the
filter's velocity noise is fitted on flights of this kind of their own (never scored), as the
projected experiment's is.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import cv2
import numpy as np

from experiments.ar_slam3d import FIT_HORIZON_FRAMES, FIT_SEEDS, MODES, RATE_HZ, SPEED_MPS, Track, trajectory
from sim.pinhole import Pinhole, render
from sim.relief import Relief, relief_terrain
from vehicle.estimators.ar_slam3d import ArSlam3d
from vehicle.models import slam3d
from vehicle.vision import ncc, susan, two_view
from vehicle.vision.triangulation import camera_matrices, triangulate

SCALE = 0.5  # 320 x 240, K halved: a frame's ray casting and SUSAN at 640 x 480 cost four times as much
MIN_MATCHES = 12  # fewer matches than this and a frame's two-view geometry is not trusted (none fitted)
CIRCLE_M, FOLLOW_M = 60.0, 10.0  # the flight's circle (inside the relief's 205 m square); smoothing of the relief


@dataclass(frozen=True)
class RenderedFlight:
    relief: Relief
    camera: Pinhole
    positions: np.ndarray  # (frames, 3) m
    rotations: np.ndarray  # (frames, 3, 3) R_wc


@dataclass
class FrontEndCounts:
    """Per flight: frames whose two-view geometry failed (too few matches, no F), matches RANSAC kept,
    points triangulated and kept (parallax), and the rotation error of the last frame (rad)."""

    failed: int = 0
    matches: int = 0
    points: int = 0
    rotation_error_rad: float = 0.0


def flight(seed: int, frames: int) -> RenderedFlight:
    """Relief of ``seed`` and the camera's true track over it: circles of CIRCLE_M around its centre."""
    relief = relief_terrain(np.random.default_rng([seed, 7]), size_px=2048)
    smooth = cv2.GaussianBlur(relief.height_m, (0, 0), FOLLOW_M / relief.metres_per_pixel)
    followed = Relief(relief.texture, smooth, relief.metres_per_pixel)
    turn = SPEED_MPS / CIRCLE_M  # rad/s
    positions, rotations = trajectory(
        np.random.default_rng([seed, 3]),
        frames,
        lambda t: np.pi / 2 + turn * t,
        followed.height_at,
        np.array([CIRCLE_M, 0.0]),
    )
    return RenderedFlight(relief, Pinhole.paper(SCALE), positions, rotations)


@functools.cache
def motion_noise() -> np.ndarray:
    """The velocity noise the filter is told (3,) m^2/s^2: as experiments.ar_slam3d.motion_noise, on
    rendered-flight tracks of their own (FIT_SEEDS; no frame rendered)."""
    m = FIT_HORIZON_FRAMES
    velocities = [np.diff(flight(seed, 1600).positions, axis=0) * RATE_HZ for seed in FIT_SEEDS]
    return np.concatenate([v[m:] - v[:-m] for v in velocities]).var(axis=0) / m


def sightings(
    camera: Pinhole,
    older: tuple[np.ndarray, np.ndarray],
    newer: tuple[np.ndarray, np.ndarray],
    baseline_m: float,
    rng: np.random.Generator,
    min_parallax_rad: float,
    rotation: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int] | None:
    """Two frames' (image, SUSAN corners): the points triangulated from their matches, in the newer
    camera (k, 3), their covariances (k, 3, 3), the rotation R from the older camera to the newer
    (3, 3) and how many matches were kept; None when the two-view geometry fails. ``rotation``: R
    known (an attitude sensor's), so only the direction of travel is fitted
    (two_view.translation_given_rotation); else R and t from E = K^T F K (the paper's VO)."""
    if rotation is None:  # the paper: RANSAC on F, then R and t from E
        fitted = ncc.matched_geometry(older[0], older[1], newer[0], newer[1], rng)
        if fitted is None or len(fitted[1]) < MIN_MATCHES:
            return None
        F, p1, p2 = fitted
        vo = two_view.relative_pose(F, camera.K, p1, p2)
    else:  # R known: RANSAC on F = K^-T [t]x R K^-1, two unknowns
        i1, i2, _ = ncc.match(older[0], older[1], newer[0], newer[1])
        known = two_view.translation_given_rotation(rotation, camera.K, older[1][i1], newer[1][i2], rng)
        if known is None or known[1].sum() < MIN_MATCHES:
            return None
        vo, inliers = known
        p1, p2 = older[1][i1][inliers], newer[1][i2][inliers]
    L = vo.t / np.linalg.norm(vo.t) * baseline_m  # the paper's metric length of L, the fitted direction
    out = triangulate(*camera_matrices(camera.K, vo.R, L), p1, p2)
    keep = out.usable & (out.parallax_rad >= min_parallax_rad)
    z = out.points[keep] @ vo.R.T + L
    cov = np.einsum("ij,njk,lk->nil", vo.R, out.covariances[keep], vo.R)
    return z, cov, vo.R, len(p1)


def fly(
    seed: int,
    frames: int,
    mode: str,
    *,
    rotation: str = "vo",
    baseline_frames: int = 10,
    min_parallax_deg: float = 2.0,
    omega_var: np.ndarray | None = None,
) -> tuple[Track, FrontEndCounts]:
    """One rendered flight of ``frames`` frames with the back end in ``mode`` (ar_slam3d.MODES), each
    frame paired with the one ``baseline_frames`` before it (module docstring); the track (landmark
    NEES NaN: the map's points have no identity) and the front end's counts. ``omega_var``: the
    velocity noise the filter is told (default: ``motion_noise()``, fitted)."""
    path = flight(seed, frames + 1)
    rng = np.random.default_rng([seed, 5])
    dt = 1.0 / RATE_HZ
    v0 = (path.positions[1] - path.positions[0]) / dt
    x0 = np.concatenate([path.positions[0] + rng.normal(0, 0.05, 3), v0 + rng.normal(0, 0.05, 3)])
    P0 = np.diag([0.05**2] * 6)
    told = motion_noise() if omega_var is None else omega_var
    slam = ArSlam3d(x0, P0, omega_var=told, seed=seed, association="nn", **MODES[mode])
    seen: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # frame -> (image, corners), the last few
    believed = {k: path.rotations[k] for k in range(baseline_frames)}  # R_wc the back end is handed
    counts, rows = FrontEndCounts(), []
    for k in range(frames + 1):
        image, _ = render(path.relief, path.camera, path.positions[k], path.rotations[k], rng)
        seen[k] = (image, susan.corners(image)[0])
        seen.pop(k - baseline_frames - 1, None)
        if k == 0:
            continue
        j = max(0, k - baseline_frames)
        if rotation == "given":
            believed[k] = path.rotations[k]
        baseline = float(np.linalg.norm(path.positions[k] - path.positions[j]))
        known = believed[k].T @ believed[j] if rotation == "given" else None
        found = sightings(path.camera, seen[j], seen[k], baseline, rng, np.deg2rad(min_parallax_deg), known)
        if found is None:
            counts.failed += 1
            z, cov = np.zeros((0, 3)), np.zeros((0, 3, 3))
            believed.setdefault(k, believed[j])
        else:
            z, cov, R_rel, matches = found
            counts.matches += matches
            counts.points += len(z)
            believed.setdefault(k, believed[j] @ R_rel.T if rotation == "vo" else path.rotations[k])
        start = time.perf_counter()
        slam.predict(dt)
        slam.frame(z, cov, believed[k])
        elapsed = (time.perf_counter() - start) * 1e3
        velocity = (path.positions[k] - path.positions[k - 1]) / dt
        head = slice(0, slam3d.HEAD)
        rows.append(
            (
                k * dt,
                path.positions[k],
                slam.x[:3].copy(),
                slam.P[:3, :3].copy(),
                slam.book.radius_m,
                (len(slam.x) - slam3d.HEAD) // slam3d.POINT,
                slam.book.added,
                elapsed,
                slam.x[head] - np.concatenate([path.positions[k], velocity]),
                slam.P[head, head].copy(),
                float("nan"),
            )
        )
    R_err = believed[frames].T @ path.rotations[frames]
    counts.rotation_error_rad = float(np.arccos(np.clip((np.trace(R_err) - 1.0) / 2.0, -1.0, 1.0)))
    return Track(*(np.array(column) for column in zip(*rows))), counts
