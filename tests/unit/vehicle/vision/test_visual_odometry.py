"""Visual odometry (vehicle.vision.odometry, two_view): motion recovered against the known motion of
synthetic 3-D scenes, planar and not, and of rendered camera frames over the simulated terrain."""

from __future__ import annotations

import re

import numpy as np
import pytest

from bus import messages as m
from bus.config import build_config
from bus.errors import ConfigError
from sim.camera import camera_frame
from sim.terrain import procedural_terrain
from vehicle.vision import two_view
from vehicle.vision.features import Features, detect, make_detector
from vehicle.vision.odometry import NoMotion, VoSpec, camera_motion, frame_motion
from vehicle.vision.visual_odometry import VisualOdometry

K = np.array([[400.0, 0.0, 320.0], [0.0, 400.0, 240.0], [0.0, 0.0, 1.0]])
DOWN = np.diag([1.0, -1.0, -1.0])  # world -> camera of a camera looking straight down


def yaw(psi: float) -> np.ndarray:
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def two_views(rng, *, relief_m: float, move=(3.0, 1.5, 0.5), turn=0.08, altitude=30.0, n=150, noise_px=0.5):
    """Pixels of n ground points (heights uniform within +-relief) seen from two downward poses, and
    the true relative motion (R, t) with X2 = R X1 + t."""
    X = np.column_stack([rng.uniform(-25, 25, n), rng.uniform(-18, 18, n), rng.uniform(-relief_m, relief_m, n)])
    C1, C2 = np.array([0.0, 0.0, altitude]), np.array([0.0, 0.0, altitude]) + np.asarray(move)
    R1, R2 = DOWN, DOWN @ yaw(turn).T

    def project(R, C):
        Xc = (X - C) @ R.T
        p = Xc @ K.T
        return p[:, :2] / p[:, 2:3] + rng.normal(scale=noise_px, size=(n, 2))

    return project(R1, C1), project(R2, C2), R2 @ R1.T, R2 @ (C1 - C2)


def angle_between(R: np.ndarray, R_true: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip((np.trace(R.T @ R_true) - 1) / 2, -1, 1))))


def test_the_eight_point_design_matrix_loses_three_ranks_over_flat_ground():
    rng = np.random.default_rng(1)
    p1, p2, _, _ = two_views(rng, relief_m=0.0, noise_px=0.0)
    x1, _ = two_view.normalise(p1)
    x2, _ = two_view.normalise(p2)
    s = np.linalg.svd(two_view.design_matrix(x1, x2), compute_uv=False)
    assert np.all(s[-3:] < 1e-9 * s[0]) and s[-4] > 1e-4 * s[0]
    p1, p2, _, _ = two_views(rng, relief_m=8.0, noise_px=0.0)
    x1, _ = two_view.normalise(p1)
    x2, _ = two_view.normalise(p2)
    s = np.linalg.svd(two_view.design_matrix(x1, x2), compute_uv=False)
    assert s[-1] < 1e-9 * s[0] and s[-2] > 1e-4 * s[0]  # one null vector: F


@pytest.mark.parametrize("seed", range(10))
def test_flat_ground_picks_the_homography_and_recovers_the_metric_motion(seed):
    rng = np.random.default_rng(seed)
    p1, p2, R, t = two_views(rng, relief_m=0.0)
    motion = camera_motion(p1, p2, K, 30.0, rng)
    assert isinstance(motion, type(motion)) and not isinstance(motion, NoMotion)
    assert motion.model == "homography" and motion.ratio > 0.45
    assert angle_between(motion.R, R) < 0.3
    assert np.linalg.norm(motion.t - t) < 0.05 * np.linalg.norm(t)


@pytest.mark.parametrize("seed", range(10))
def test_relief_picks_the_fundamental_matrix_and_recovers_the_motion(seed):
    rng = np.random.default_rng(100 + seed)
    p1, p2, R, t = two_views(rng, relief_m=10.0)
    motion = camera_motion(p1, p2, K, 30.0, rng)
    assert not isinstance(motion, NoMotion)
    assert motion.model == "fundamental" and motion.ratio < 0.45
    assert angle_between(motion.R, R) < 0.5
    direction = np.degrees(np.arccos(motion.t @ t / np.linalg.norm(motion.t) / np.linalg.norm(t)))
    assert direction < 3.0
    # metric from the altitude taken as the scene's median depth: off by the relief's asymmetry only
    assert abs(np.linalg.norm(motion.t) / np.linalg.norm(t) - 1) < 0.1


@pytest.mark.parametrize("relief_m", [0.0, 10.0])
def test_with_the_rotation_known_the_direction_of_travel_is_found_and_wrong_matches_are_left_out(relief_m):
    """Known R (an attitude sensor's): t from two pairs inside RANSAC, over flat ground too (where F is
    not determined), its sign by cheirality; a fifth of the pairs shuffled are not inliers."""
    rng = np.random.default_rng(7)
    p1, p2, R, t = two_views(rng, relief_m=relief_m)
    wrong = rng.choice(len(p2), size=len(p2) // 5, replace=False)
    p2[wrong] = p2[np.roll(wrong, 1)]
    pose, inliers = two_view.translation_given_rotation(R, K, p1, p2, rng)
    direction = np.degrees(np.arccos(pose.t @ t / np.linalg.norm(pose.t) / np.linalg.norm(t)))
    assert direction < 1.0 and np.linalg.norm(pose.t) == pytest.approx(1.0)
    assert not inliers[wrong].any() and inliers.sum() >= 0.9 * (len(p1) - len(wrong))
    assert pose.in_front == inliers.sum()


def test_with_the_rotation_known_too_few_pairs_is_no_direction():
    rng = np.random.default_rng(0)
    p1, p2, R, _ = two_views(rng, relief_m=5.0, n=1)
    assert two_view.translation_given_rotation(R, K, p1, p2, rng) is None


def test_too_few_matches_is_no_motion():
    rng = np.random.default_rng(0)
    p1, p2, _, _ = two_views(rng, relief_m=0.0, n=6)
    assert isinstance(camera_motion(p1, p2, K, 30.0, rng), NoMotion)


def rendered_pairs(seeds, speed_m=1.0, turn=0.05):
    """Frames (80 px, 0.1 m/px) of the simulated terrain from pose 1 and from pose 1 moved by
    [forward, left, yaw], with that motion."""
    terrain = procedural_terrain(np.random.default_rng(7), size_px=1200, metres_per_pixel=0.1)
    detector = make_detector("sift")
    for seed in seeds:
        rng = np.random.default_rng(seed)
        pose1 = np.array([rng.uniform(-40, 40), rng.uniform(-40, 40), rng.uniform(-np.pi, np.pi)])
        delta = np.array([speed_m * rng.uniform(0.5, 1.0), rng.normal(scale=0.1), rng.normal(scale=turn)])
        c, s = np.cos(pose1[2]), np.sin(pose1[2])
        pose2 = pose1 + np.array([c * delta[0] - s * delta[1], s * delta[0] + c * delta[1], delta[2]])
        f1 = detect(camera_frame(terrain, pose1, rng), detector)
        f2 = detect(camera_frame(terrain, pose2, rng), detector)
        yield f1, f2, delta, rng


def test_rendered_frames_give_the_motion_with_a_consistent_covariance():
    errors, nees, failed = [], [], 0
    for f1, f2, delta, rng in rendered_pairs(range(40)):
        motion = frame_motion(f1, f2, 80, 0.1, rng)
        if isinstance(motion, NoMotion):  # an 80 px frame holds 10 to 25 SIFT keypoints
            failed += 1
            continue
        e = motion.delta - delta
        errors.append(e)
        nees.append(e @ np.linalg.solve(motion.covariance, e))
    errors = np.array(errors)
    assert failed <= 4
    assert np.sqrt(np.mean(errors[:, :2] ** 2)) < 0.03  # metres per frame
    assert np.degrees(np.sqrt(np.mean(errors[:, 2] ** 2))) < 0.5
    # ANEES of the 3-dof motion over 40 pairs inside the two-sided 95 % band
    lo, hi = two_sided_band(3, len(nees))
    assert lo <= np.mean(nees) <= hi, np.mean(nees)


def two_sided_band(dof: int, runs: int) -> tuple[float, float]:
    from scipy.stats import chi2

    return chi2.ppf(0.025, dof * runs) / runs, chi2.ppf(0.975, dof * runs) / runs


def test_a_frame_without_features_and_frames_that_do_not_overlap_are_no_motion():
    (f1, f2, _, rng), *_ = rendered_pairs([3])
    empty = Features(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 128), np.float32))
    assert "without features" in frame_motion(f1, empty, 80, 0.1, rng).reason
    (far, *_), *_ = rendered_pairs([4])  # another place on the terrain
    result = frame_motion(f1, far, 80, 0.1, rng, VoSpec())
    assert isinstance(result, NoMotion) and ("matches" in result.reason or "degenerate" in result.reason)


def frame(seq: int, pixels: np.ndarray) -> m.CameraFrame:
    return m.CameraFrame(1, seq * 100_000, seq, pixels, 0.1)


def test_the_front_end_says_unknown_then_measures_then_grows_the_sigma_of_what_it_cannot_see():
    refused = []
    vo = VisualOdometry(1, reject=lambda *a: refused.append(a[0]))
    terrain = procedural_terrain(np.random.default_rng(7), size_px=1200, metres_per_pixel=0.1)
    rng = np.random.default_rng(0)
    first = camera_frame(terrain, np.array([0.0, 0.0, 0.3]), rng)
    second = camera_frame(terrain, np.array([0.4, 0.0, 0.3]), rng)
    (start,) = vo.on_frame(frame(0, first))
    assert start.speed_mps == 0 and start.speed_var == 100.0 and np.isinf(start.yaw_rate_var)
    (moved,) = vo.on_frame(frame(1, second))
    assert moved.stamp_us == 1 and moved.seq == 1 and abs(moved.speed_mps - 4.0) < 0.3
    assert np.isfinite(moved.yaw_rate_var) and moved.speed_var < 0.1
    flat = np.full((80, 80), 90, np.uint8)
    assert vo.on_frame(frame(2, flat)) == [] and not refused  # garbage: the SLAM front end reports it
    far = camera_frame(terrain, np.array([30.0, 30.0, 0.3]), rng)  # no overlap with the last good frame
    (unseen,) = vo.on_frame(frame(3, far))
    assert refused == ["no_visual_motion"] and unseen.speed_mps == moved.speed_mps
    assert unseen.speed_var == pytest.approx(moved.speed_var + (1.0 * 0.2) ** 2) and np.isinf(unseen.yaw_rate_var)


@pytest.mark.parametrize(
    "changes, message",
    [
        ({"vehicle": {"odometry": "visual"}}, "needs a camera"),
        ({"vehicle": {"visual_odometry_vehicles": [1]}}, "needs a camera"),
        ({"vehicle": {"odometry": "visual", "fusion_horizon_s": 0.05}, "sensors": {"camera_rate_hz": 10}}, "horizon"),
        ({"vehicle": {"visual_odometry_vehicles": [9]}, "sensors": {"camera_rate_hz": 10}}, "not in the swarm: [9]"),
    ],
)
def test_visual_odometry_configurations_that_cannot_work_are_refused_by_name(changes, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        build_config({"world": {"vehicles": 2}, **changes})
