"""The AR-EKF-SLAM paper's front end (SUSAN corners, NCC matching, RANSAC on F) against SIFT and ORB
(Lowe's ratio test, RANSAC on F) on the same rendered frames: a pinhole camera (the paper's K, scaled)
flying over terrain with relief (sim.relief, sim.pinhole). Pure; seeded.

Per pair of consecutive frames, with the truth of the first frame's depth:
- repeatability: of the first frame's keypoints whose ground point is seen in the second frame (inside
  it, not hidden: its depth there within 5 % of the second frame's own depth at that pixel), the share
  with a keypoint of the second frame within ``REPEAT_PX`` of where it projects;
- correct matches: the matches RANSAC keeps whose second point lies within ``CORRECT_PX`` of the true
  projection of the first, counted, and as a share of what RANSAC keeps;
- time per frame: detection (and description or patches) of one frame, and matching of one pair
  with RANSAC, in milliseconds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from bus.sensors.camera3d import look
from sim.pinhole import Pinhole, render
from sim.relief import Relief, relief_terrain
from vehicle.vision import ncc, susan, two_view
from vehicle.vision.features import detect, make_detector
from vehicle.vision.odometry import match as descriptor_match

FRONT_ENDS = ("susan-ncc", "sift", "orb")
REPEAT_PX, CORRECT_PX = 1.5, 2.0


@dataclass(frozen=True)
class Flight:
    """Frames (n, H, W) uint8, their depth (n, H, W) m, camera centres (n, 3) and rotations (n, 3, 3)."""

    frames: np.ndarray
    depth: np.ndarray
    centres: np.ndarray
    rotations: np.ndarray
    camera: Pinhole


def fly(
    seed: int,
    frames: int,
    *,
    scale: float = 0.5,
    step_m: float = 1.0,
    altitude_m: float = 30.0,
    pitch_deg: float = 50.0,
) -> Flight:
    """A climbing, turning flight over relief: one frame every ``step_m`` metres."""
    rng = np.random.default_rng(seed)
    relief: Relief = relief_terrain(rng, size_px=2048)
    camera = Pinhole.paper(scale)
    out = []
    for k in range(frames):
        yaw = 0.3 + 0.01 * k
        C = np.array([-40.0 + step_m * k * np.cos(yaw), -20.0 + step_m * k * np.sin(yaw), altitude_m + 0.05 * k])
        R = look(yaw, np.deg2rad(pitch_deg))
        frame, depth = render(relief, camera, C, R, rng)
        out.append((frame, depth, C, R))
    return Flight(*(np.array(x) for x in zip(*out)), camera=camera)


def _truth(flight: Flight, k: int, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where the ground under ``points`` (m, 2) of frame k projects in frame k + 1 (m, 2), and whether
    it is seen there (m,)."""
    K_inv = np.linalg.inv(flight.camera.K)
    cols, rows = np.rint(points[:, 0]).astype(int), np.rint(points[:, 1]).astype(int)
    depth = flight.depth[k][rows, cols]
    rays = np.column_stack([points, np.ones(len(points))]) @ K_inv.T @ flight.rotations[k].T
    X = flight.centres[k] + np.where(np.isfinite(depth), depth, 0.0)[:, None] * rays
    projected, z = flight.camera.project(flight.rotations[k + 1], flight.centres[k + 1], X)
    width, height = flight.camera.size
    inside = np.isfinite(depth) & (z > 0) & (projected[:, 0] >= 0) & (projected[:, 0] <= width - 1)
    inside &= (projected[:, 1] >= 0) & (projected[:, 1] <= height - 1)
    seen = np.zeros(len(points), bool)
    at = np.flatnonzero(inside)
    there = flight.depth[k + 1][np.rint(projected[at, 1]).astype(int), np.rint(projected[at, 0]).astype(int)]
    seen[at] = np.abs(there - z[at]) <= 0.05 * z[at]
    return projected, seen


def _keypoints(front_end: str, frame: np.ndarray, detector):
    if front_end == "susan-ncc":
        return susan.corners(frame)[0]
    return detect(frame, detector)


def _matches(front_end: str, frames, keypoints, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Pixels (m, 2), (m, 2) of the matches RANSAC on F keeps."""
    if front_end == "susan-ncc":
        fitted = ncc.matched_geometry(frames[0], keypoints[0], frames[1], keypoints[1], rng)
        return (fitted[1], fitted[2]) if fitted is not None else (np.zeros((0, 2)), np.zeros((0, 2)))
    i, j = descriptor_match(keypoints[0], keypoints[1], 0.75)
    p1, p2 = keypoints[0].points_px[i], keypoints[1].points_px[j]
    fitted = two_view.ransac(
        two_view.eight_point, two_view.epipolar_distances, 8, p1, p2, rng, threshold=1.5**2, iterations=200
    )
    return (p1[fitted[1]], p2[fitted[1]]) if fitted is not None else (np.zeros((0, 2)), np.zeros((0, 2)))


def compare(flight: Flight, seed: int = 0) -> dict[str, dict[str, float]]:
    """Per front end: mean keypoints per frame, repeatability, correct matches per pair and their
    share, detection ms per frame, matching ms per pair (module docstring)."""
    out = {}
    for front_end in FRONT_ENDS:
        rng = np.random.default_rng(seed)
        detector = None if front_end == "susan-ncc" else make_detector(front_end)
        start = time.perf_counter()
        keypoints = [_keypoints(front_end, frame, detector) for frame in flight.frames]
        detect_ms = (time.perf_counter() - start) * 1e3 / len(flight.frames)
        points = [k if front_end == "susan-ncc" else k.points_px for k in keypoints]
        repeat, correct, share, match_ms = [], [], [], 0.0
        for k in range(len(flight.frames) - 1):
            projected, seen = _truth(flight, k, points[k])
            if seen.any() and len(points[k + 1]):
                nearest = np.min(np.linalg.norm(projected[seen][:, None] - points[k + 1][None], axis=-1), axis=1)
                repeat.append(float(np.mean(nearest <= REPEAT_PX)))
            start = time.perf_counter()
            p1, p2 = _matches(front_end, flight.frames[k : k + 2], keypoints[k : k + 2], rng)
            match_ms += (time.perf_counter() - start) * 1e3
            true, seen1 = _truth(flight, k, p1) if len(p1) else (np.zeros((0, 2)), np.zeros(0, bool))
            right = seen1 & (np.linalg.norm(true - p2, axis=1) <= CORRECT_PX) if len(p1) else np.zeros(0, bool)
            correct.append(int(right.sum()))
            share.append(float(right.mean()) if len(right) else 0.0)
        out[front_end] = {
            "keypoints": float(np.mean([len(p) for p in points])),
            "repeatability": float(np.mean(repeat)) if repeat else 0.0,
            "correct_matches": float(np.mean(correct)),
            "correct_share": float(np.mean(share)),
            "detect_ms": detect_ms,
            "match_ms": match_ms / max(1, len(flight.frames) - 1),
        }
    return out
