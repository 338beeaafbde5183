"""The rendered 3-D chain's front end between two frames (experiments.ar_slam3d_rendered): a pair of
frames' matched pixels (``matched_pairs``: SUSAN corners matched by NCC across the pair, the paper's;
or CornerTracks.pairs, corners followed frame to frame), the relative pose fitted inside RANSAC
(``relative``: the paper's VO, or only the direction of travel with the rotation given), the pixels
that agree with it triangulated (``triangulated``, the paper's least squares) into a frame's points
(``frame_points``: from one pair, ``_pair_points``, and from a shorter pair where the long one finds no
geometry), with an optional referee pair (``refereed``). Pure; seeded.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from bus.statistics import gate_threshold
from sim.pinhole import Pinhole
from vehicle.vision import ncc, two_view
from vehicle.vision.triangulation import camera_matrices, in_second_camera, triangulate

MIN_MATCHES = 12  # fewer matches than this and a frame's two-view geometry is not trusted (none fitted)


@dataclass(frozen=True)
class PairPoints:
    """What a pair of frames (older, k) gives (``_pair``): the relative pose, the points triangulated
    in camera k (m, 3), their covariances (m, 3, 3), their parallax (m,) rad (NaN where the
    triangulation refused the pair) and their corners' indices in frame k (m,)."""

    pose: two_view.RelativePose
    z: np.ndarray
    cov: np.ndarray
    parallax: np.ndarray
    corners: np.ndarray


class FlightView(Protocol):
    """What the front end reads of a flight (experiments.ar_slam3d_rendered.RenderedFlight): its camera
    and its true positions (frames, 3) m (the paper's metric baseline between two frames is given)."""

    camera: Pinhole
    positions: np.ndarray


def relative(
    camera: Pinhole, p1: np.ndarray, p2: np.ndarray, rng: np.random.Generator, rotation: np.ndarray | None
) -> tuple[two_view.RelativePose, np.ndarray] | None:
    """The older camera to the newer from matched pixels p1, p2 (m, 2), and which pairs agree with it
    (m,): RANSAC on F then R and t from E = K^T F K (the paper's VO), or with the rotation known (an
    attitude sensor's) only the direction of travel (two_view.translation_given_rotation). None when
    fewer than MIN_MATCHES pairs agree."""
    if rotation is None:
        fitted = ncc.fundamental(p1, p2, rng)
        if fitted is None:
            return None
        inliers = fitted[1]
        pose = two_view.relative_pose(fitted[0], camera.K, p1[inliers], p2[inliers])
    else:
        known = two_view.translation_given_rotation(rotation, camera.K, p1, p2, rng)
        if known is None:
            return None
        pose, inliers = known
    return (pose, inliers) if inliers.sum() >= MIN_MATCHES else None


def triangulated(
    camera: Pinhole,
    pose: two_view.RelativePose,
    p1: np.ndarray,
    p2: np.ndarray,
    baseline_m: float,
    sigma_px: float = 1.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs triangulated (vehicle.vision.triangulation) with ``pose`` at the paper's metric length of
    L, each pixel's noise ``sigma_px``: points in the newer camera (m, 3), their covariances (m, 3, 3)
    and their parallax (m,) rad (NaN where the triangulation refuses the pair)."""
    L = pose.t / np.linalg.norm(pose.t) * baseline_m
    out = triangulate(*camera_matrices(camera.K, pose.R, L), p1, p2, sigma_px=sigma_px)
    z, cov = in_second_camera(pose.R, L, out.points, out.covariances)
    return z, cov, np.where(out.usable, out.parallax_rad, np.nan)


def refereed(
    z: np.ndarray, cov: np.ndarray, corners: np.ndarray, z_ref: np.ndarray, cov_ref: np.ndarray, corners_ref
) -> np.ndarray:
    """Which points (m,) a second triangulation of the same corner of the newer frame (``corners``: its
    index in that frame's corners; ``*_ref``: from another older frame) confirms: the two within their
    covariances (chi-square, 3 dof, 0.999). A point the other pair did not triangulate is not confirmed."""
    row = {int(c): i for i, c in enumerate(corners_ref)}
    ok = np.zeros(len(z), bool)
    gate = gate_threshold(3, 0.999)
    for i, c in enumerate(corners):
        r = row.get(int(c))
        if r is None or not np.isfinite(z_ref[r]).all():
            continue
        d = z[i] - z_ref[r]
        ok[i] = float(d @ np.linalg.solve(cov[i] + cov_ref[r], d)) <= gate
    return ok


def rotation_angle_rad(R: np.ndarray) -> float:
    """The angle (rad) of rotation R (3, 3)."""
    return float(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)))


def frame_points(
    path: FlightView,
    pairs: Callable[[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]],
    believed: dict,
    k: int,
    olders: tuple[int, ...],
    referee: bool,
    rng: np.random.Generator,
    rotation: str,
    min_parallax_rad: float,
    sigma_px: float,
) -> tuple[int, np.ndarray, np.ndarray, two_view.RelativePose | None, int]:
    """Frame k's points (``_pair_points``) from the pair with the frame ``olders[0]`` before, and where
    its geometry fails from the next of ``olders`` in turn: the older frame used (the last tried when
    none holds), then ``_pair_points``' answer. ``referee``: each pair confirmed by the frame half
    its span before."""
    for older in olders:
        j = max(0, k - older)
        h = k - older // 2 if referee else j  # the referee's frame (none: j)
        z, cov, pose, matches = _pair_points(
            path, pairs, believed, (j, h, k), rng, rotation, min_parallax_rad, sigma_px
        )
        if pose is not None:
            break
    return j, z, cov, pose, matches


def _pair_points(
    path: FlightView,
    pairs: Callable[[int, int], tuple[np.ndarray, np.ndarray, np.ndarray]],
    believed: dict,
    frames: tuple[int, int, int],
    rng: np.random.Generator,
    rotation: str,
    min_parallax_rad: float,
    sigma_px: float,
) -> tuple[np.ndarray, np.ndarray, two_view.RelativePose | None, int]:
    """Frame k's points from the pair (j, k) (``_pair``) of ``frames`` (j, h, k) with at least
    ``min_parallax_rad`` of parallax and, for h between j and k, confirmed by the pair (h, k)
    (``_confirmed``): points (n, 3), covariances (n, 3, 3), the pair's relative pose (None when its
    geometry failed) and how many matches it kept. ``believed``: the rotations the back end is handed,
    by frame (frame k's set where it is given)."""
    j, h, k = frames
    known = believed[k].T @ believed[j] if rotation == "given" else None
    found = _pair(path, pairs, j, k, rng, known, sigma_px)
    if found is None:
        return np.zeros((0, 3)), np.zeros((0, 3, 3)), None, 0
    keep = found.parallax >= min_parallax_rad  # NaN (refused) is not
    if h > j:
        known_h = believed[k].T @ believed[h] if rotation == "given" else None
        keep &= _confirmed(found, _pair(path, pairs, h, k, rng, known_h, sigma_px))
    return found.z[keep], found.cov[keep], found.pose, len(found.z)


def _confirmed(found: PairPoints, other: PairPoints | None) -> np.ndarray:
    """Which of ``found``'s points the pair ``other`` (the same newer frame) confirms (``refereed``); none
    when that pair's geometry failed."""
    if other is None:
        return np.zeros(len(found.z), bool)
    usable = np.where(np.isfinite(other.parallax)[:, None], other.z, np.nan)  # refused there: NaN
    return refereed(found.z, found.cov, found.corners, usable, other.cov, other.corners)


def matched_pairs(detected: dict, j: int, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The paper's pairs: frames j and k's SUSAN corners (``detected``: frame -> (image, corners))
    matched by NCC across the baseline; their pixels in j (m, 2), in k (m, 2), and their corners'
    indices in frame k (m,)."""
    i1, i2, _ = ncc.match(detected[j][0], detected[j][1], detected[k][0], detected[k][1])
    return detected[j][1][i1], detected[k][1][i2], i2


def _pair(
    path: FlightView, pairs, j: int, k: int, rng: np.random.Generator, rotation, sigma_px: float
) -> PairPoints | None:
    """Frames j and k's pairs (``pairs(j, k)``: ``matched_pairs``, or ``CornerTracks.pairs`` where the
    corners are followed), the relative pose fitted (``relative``) and the pairs that agree with it
    triangulated; None when the geometry fails."""
    p1, p2, i2 = pairs(j, k)
    fitted = relative(path.camera, p1, p2, rng, rotation) if len(p1) >= MIN_MATCHES else None
    if fitted is None:
        return None
    pose, inliers = fitted
    baseline = float(np.linalg.norm(path.positions[k] - path.positions[j]))
    p1, p2 = p1[inliers], p2[inliers]
    return PairPoints(pose, *triangulated(path.camera, pose, p1, p2, baseline, sigma_px), i2[inliers])
