"""The terrain and the down-looking camera: deterministic, feature-rich, and geometrically right
(a mark on the ground appears in the frame where the vehicle's pose says it must, and the front
end turns it back into the range and bearing it was seen at)."""

import cv2
import numpy as np
import pytest

from bus.errors import ConfigError
from sim.camera import camera_frame
from sim.terrain import Terrain, load_terrain, procedural_terrain
from vehicle.vision.features import body_to_world, detect, make_detector, range_bearing, thin


@pytest.fixture(scope="module")
def terrain() -> Terrain:
    return procedural_terrain(np.random.default_rng(5), size_px=2048, metres_per_pixel=0.1)


def test_the_terrain_is_deterministic_and_sift_finds_thousands_of_keypoints(terrain):
    again = procedural_terrain(np.random.default_rng(5), size_px=2048, metres_per_pixel=0.1)
    other = procedural_terrain(np.random.default_rng(6), size_px=2048, metres_per_pixel=0.1)
    assert np.array_equal(terrain.image, again.image) and not np.array_equal(terrain.image, other.image)
    assert terrain.image.shape == (2048, 2048) and terrain.size_m == pytest.approx((204.8, 204.8))
    keypoints = make_detector("sift").detect(terrain.image, None)
    assert len(keypoints) > 5000


def test_a_mark_on_the_ground_appears_where_the_pose_says(terrain):
    image = terrain.image.copy()
    mark_m = np.array([12.0, -7.0])
    col, row = np.rint(terrain.to_pixel(mark_m)).astype(int)
    image[:] = 0
    cv2.circle(image, (int(col), int(row)), 2, 255, -1)
    marked = Terrain(image, terrain.metres_per_pixel)
    rng = np.random.default_rng(0)
    for heading in (0.0, 0.7, 2.0, -2.5):
        pose = np.array([10.0 + np.cos(heading), -6.0 - np.sin(heading), heading])
        frame = camera_frame(marked, pose, rng, size_px=80, noise_sigma=0.0)
        rows, cols = np.nonzero(frame > 128)
        seen = range_bearing(np.array([[cols.mean(), rows.mean()]]), 80, terrain.metres_per_pixel)
        np.testing.assert_allclose(body_to_world(pose, seen)[0], mark_m, atol=0.1)  # within a pixel


def test_frames_are_noisy_grey_windows_of_the_right_size(terrain):
    rng = np.random.default_rng(1)
    clean = camera_frame(terrain, np.array([0.0, 0.0, 0.3]), rng, size_px=80, noise_sigma=0.0)
    noisy = camera_frame(terrain, np.array([0.0, 0.0, 0.3]), rng, size_px=80, noise_sigma=2.0)
    assert clean.shape == (80, 80) and clean.dtype == np.uint8
    assert 1.5 < np.std(noisy.astype(float) - clean) < 2.5
    assert camera_frame(terrain, np.array([500.0, 0.0, 0.0]), rng).max() <= 10  # beyond the image: black


def test_thinning_keeps_the_strongest_keypoint_per_cell(terrain):
    frame = camera_frame(terrain, np.array([3.0, 4.0, 0.5]), np.random.default_rng(2), size_px=320)
    features = detect(frame, make_detector("sift"))
    kept = thin(features, cell_px=30)
    assert 0 < len(kept.responses) < len(features.responses)
    cells = [tuple(c) for c in (kept.points_px // 30).astype(int)]
    assert len(cells) == len(set(cells))  # one per cell
    for point, response in zip(kept.points_px, kept.responses):
        same = np.all((features.points_px // 30).astype(int) == (point // 30).astype(int), axis=1)
        assert response == features.responses[same].max()  # the strongest of its cell
    assert len(detect(np.zeros((80, 80), np.uint8), make_detector("orb")).responses) == 0


def test_a_missing_orthophoto_is_a_one_line_error(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_terrain(tmp_path / "nope.png", 0.1)
    (tmp_path / "bad.png").write_bytes(b"not an image")
    with pytest.raises(ConfigError, match="not a readable"):
        load_terrain(tmp_path / "bad.png", 0.1)
