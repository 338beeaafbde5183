"""The AR-EKF-SLAM paper's whole 3-D system on rendered frames: the camera of experiments.ar_slam3d
(the paper's K scaled by ``SCALE``, 10 frames a second, 5 m/s, 15 m over the ground), looking
``PITCH_DEG`` down, flies circles over terrain with hills and buildings (sim.relief); each frame is
rendered by ray casting (sim.pinhole.render, grey-level noise); the paper's front end finds SUSAN
corners (vehicle.vision.susan) and matches them by NCC (vehicle.vision.ncc) with the frame ``baseline_frames``
before (``tracked``: follows them from frame to frame instead, vehicle.vision.corner_tracks, and
pairs the two frames through the tracks they share); the relative pose is fitted inside RANSAC
(experiments.rendered_front_end); the matched corners that agree with it are triangulated (vehicle.vision.triangulation,
the paper's least squares) and fused by the 6 + 3n back end (vehicle.estimators.ar_slam3d) with nn
association: no landmark ids, no projected points. Pure; seeded.

What is given, as in the paper: the metric length of the baseline between the two frames (VO's
translation has no scale), and the first ``baseline_frames`` frames' rotations (a surveyed start).
``rotation``: "vo", the paper's visual odometry, fits F, takes R and t from E = K^T F K by cheirality
(vehicle.vision.two_view) and chains each frame's rotation from the frame ``baseline_frames`` before;
"given" hands the back end the true rotation (an attitude sensor's) and fits only the direction of
travel (two_view.translation_given_rotation).
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

from experiments.ar_slam3d import (
    FIT_HORIZON_FRAMES,
    FIT_SEEDS,
    MODES,
    RATE_HZ,
    SPEED_MPS,
    Track,
    track_row,
    trajectory,
)
from experiments.rendered_front_end import frame_points, matched_pairs, rotation_angle_rad
from sim.pinhole import Pinhole, render
from sim.relief import Relief, relief_terrain
from vehicle.estimators.ar_slam3d import ArSlam3d
from vehicle.vision import susan
from vehicle.vision.corner_tracks import CornerTracks

SCALE = 0.5  # 320 x 240, K halved: a frame's ray casting and SUSAN at 640 x 480 cost four times as much
CIRCLE_M, FOLLOW_M = 60.0, 10.0  # the flight's circle (inside the relief's 205 m square); smoothing of the relief
PITCH_DEG = 45.0  # below the horizon: the ground in the frame's middle about 21 m away, inside the paper's R of 25 m


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


def flight(seed: int, frames: int, pitch_deg: float = PITCH_DEG) -> RenderedFlight:
    """Relief of ``seed`` and the camera's true track over it: circles of CIRCLE_M around its centre,
    the camera ``pitch_deg`` below the horizon."""
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
        np.deg2rad(pitch_deg),
    )
    return RenderedFlight(relief, Pinhole.paper(SCALE), positions, rotations)


@functools.cache
def motion_noise() -> np.ndarray:
    """The velocity noise the filter is told (3,) m^2/s^2: as experiments.ar_slam3d.motion_noise, on
    rendered-flight tracks of their own (FIT_SEEDS; no frame rendered)."""
    m = FIT_HORIZON_FRAMES
    velocities = [np.diff(flight(seed, 1600).positions, axis=0) * RATE_HZ for seed in FIT_SEEDS]
    return np.concatenate([v[m:] - v[:-m] for v in velocities]).var(axis=0) / m


def fly(
    seed: int,
    frames: int,
    mode: str,
    *,
    rotation: str = "vo",
    baseline_frames: int = 10,
    min_parallax_deg: float = 2.0,
    omega_var: np.ndarray | None = None,
    referee: bool = False,
    tracked: bool = False,
    pitch_deg: float = PITCH_DEG,
    regrow: bool = False,
    fallback_frames: int | None = None,
    sigma_px: float = 1.0,
) -> tuple[Track, FrontEndCounts]:
    """One rendered flight of ``frames`` frames with the back end in ``mode`` (ar_slam3d.MODES), each
    frame paired with the one ``baseline_frames`` before it (module docstring); the track (landmark
    NEES NaN: the map's points have no identity) and the front end's counts. ``omega_var``: the
    velocity noise the filter is told (default: ``motion_noise()``, fitted). ``referee``: a point is
    kept only where the frame ``baseline_frames // 2`` before confirms it (rendered_front_end.refereed).
    ``tracked``: the pairs from corners followed frame to frame (vehicle.vision.corner_tracks), not matched across the
    baseline. ``regrow``: an emptied local map takes R out to the frame's points at once (ar_ekf_slam.regrown_radius).
    ``fallback_frames``: where the pair with the frame ``baseline_frames`` before finds no geometry, the
    pair with the frame this many before (fewer tracks survive the longer baseline). ``sigma_px``: the
    pixel noise the triangulation is told, per coordinate (experiments.rendered_noise.tracked_pixel_sigma:
    the followed corners' measured on flights of their own)."""
    path = flight(seed, frames + 1, pitch_deg)
    rng = np.random.default_rng([seed, 5])
    dt = 1.0 / RATE_HZ
    v0 = (path.positions[1] - path.positions[0]) / dt
    x0 = np.concatenate([path.positions[0] + rng.normal(0, 0.05, 3), v0 + rng.normal(0, 0.05, 3)])
    P0 = np.diag([0.05**2] * 6)
    told = motion_noise() if omega_var is None else omega_var
    slam = ArSlam3d(x0, P0, omega_var=told, seed=seed, association="nn", regrow=regrow, **MODES[mode])
    detected: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # frame -> (image, SUSAN corners), the last few
    tracks = CornerTracks() if tracked else None
    pairs = tracks.pairs if tracks is not None else functools.partial(matched_pairs, detected)
    believed = {k: path.rotations[k] for k in range(baseline_frames)}  # R_wc the back end is handed
    counts, rows = FrontEndCounts(), []
    for k in range(frames + 1):
        image, _ = render(path.relief, path.camera, path.positions[k], path.rotations[k], rng)
        detected[k] = (image, susan.corners(image)[0].astype(float))
        detected.pop(k - baseline_frames - 1, None)
        if tracks is not None:
            tracks.step(k, *detected[k])
        if k == 0:
            continue
        if rotation == "given":
            believed[k] = path.rotations[k]
        olders = (baseline_frames,) if fallback_frames is None else (baseline_frames, fallback_frames)
        parallax = np.deg2rad(min_parallax_deg)
        j, z, cov, pose, matches = frame_points(
            path, pairs, believed, k, olders, referee, rng, rotation, parallax, sigma_px
        )
        counts.failed += pose is None
        counts.matches += matches
        counts.points += len(z)
        believed.setdefault(k, believed[j] if pose is None else believed[j] @ pose.R.T)
        start = time.perf_counter()
        slam.predict(dt)
        slam.frame(z, cov, believed[k])
        elapsed = (time.perf_counter() - start) * 1e3
        rows.append(track_row(slam, k, path.positions, elapsed, float("nan")))  # no identities: no landmark NEES
    counts.rotation_error_rad = rotation_angle_rad(believed[frames].T @ path.rotations[frames])
    return Track(*(np.array(column) for column in zip(*rows))), counts
