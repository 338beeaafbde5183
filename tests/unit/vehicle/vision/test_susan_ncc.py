"""SUSAN corners (vehicle.vision.susan) on synthetic corners, and NCC matching with RANSAC on F
(vehicle.vision.ncc) on a textured frame moved by a known shift."""

from __future__ import annotations

import cv2
import numpy as np

from sim.terrain import procedural_terrain
from vehicle.vision.ncc import NccSpec, match, matched_geometry
from vehicle.vision.susan import corners, mask_offsets

RECTANGLE = ((50, 60), (130, 140))  # (col, row) of two opposite corners
TRIANGLE = ((160, 40), (190, 110), (150, 100))


def synthetic(rng: np.random.Generator) -> np.ndarray:
    image = np.full((200, 220), 40, np.uint8)
    cv2.rectangle(image, RECTANGLE[0], RECTANGLE[1], 200, thickness=-1)
    cv2.fillPoly(image, [np.array(TRIANGLE, np.int32)], 140)
    image = cv2.GaussianBlur(image, (0, 0), 0.7)
    return np.clip(image + rng.normal(0, 2.0, image.shape), 0, 255).astype(np.uint8)


def test_the_mask_is_smith_and_brady_s_37_pixels():
    offsets = mask_offsets()
    assert len(offsets) == 37 and np.all(np.hypot(*offsets.T) <= 3.4)


def test_susan_finds_the_corners_and_nothing_on_edges_or_flat_ground():
    image = synthetic(np.random.default_rng(0))
    found, _ = corners(image)
    (c0, r0), (c1, r1) = RECTANGLE
    truth = np.array([(c0, r0), (c1, r0), (c0, r1), (c1, r1), *TRIANGLE], float)
    distance = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=-1)
    assert np.all(distance.min(axis=0) <= 3.0), distance.min(axis=0)  # every corner found (a blurred acute one: 3 px)
    assert np.all(distance.min(axis=1) <= 4.0), found[distance.min(axis=1) > 4.0]  # nothing else
    edges = np.array([((c0 + c1) / 2, r0), (c0, (r0 + r1) / 2), ((c0 + c1) / 2, (r0 + r1) / 2)])
    assert np.linalg.norm(found[:, None, :] - edges[None, :, :], axis=-1).min() > 3.0


def test_ncc_matches_a_moved_frame_and_ransac_keeps_only_the_motion():
    rng = np.random.default_rng(1)
    ground = procedural_terrain(np.random.default_rng(2), size_px=512).image
    shift = np.array([6, -3])  # (col, row)
    first = ground[100:340, 100:420]
    second = ground[100 - shift[1] : 340 - shift[1], 100 - shift[0] : 420 - shift[0]]
    first, second = (np.clip(f + rng.normal(0, 2.0, f.shape), 0, 255).astype(np.uint8) for f in (first, second))
    p1, _ = corners(first)
    p2, _ = corners(second)
    i1, i2, score = match(first, p1, second, p2, NccSpec(max_disparity_px=20.0))
    displacement = p2[i2] - p1[i1]
    right = np.linalg.norm(displacement - shift, axis=1) <= 1.0
    assert len(i1) >= 30 and right.mean() >= 0.9 and score.min() >= 0.8
    fitted = matched_geometry(first, p1, second, p2, rng, NccSpec(max_disparity_px=20.0))
    assert fitted is not None
    _, q1, q2 = fitted  # RANSAC on F drops what leaves the epipolar lines (not what slides along them)
    kept_right = np.linalg.norm(q2 - q1 - shift, axis=1) <= 1.0
    assert len(q1) >= 30 and kept_right.mean() >= max(0.9, right.mean())


def test_corners_only_at_the_border_or_none_at_all_are_no_matches_not_an_error():
    """A frame whose corners all lie within a patch's half-size of the border (or that has none) has
    no patch to match: no pairs, and RANSAC is not tried (a rendered flight met it over a blank field)."""
    image = np.full((60, 80), 100, np.uint8)
    border = np.array([[1.0, 1.0], [78.0, 30.0], [40.0, 58.0]])
    for points in (border, np.zeros((0, 2))):
        i1, i2, score = match(image, points, image, border)
        assert len(i1) == len(i2) == len(score) == 0
        assert matched_geometry(image, points, image, border, np.random.default_rng(0)) is None
