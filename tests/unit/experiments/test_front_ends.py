"""The front-end comparison (experiments.front_ends) measures what it says on a short flight over
relief: the paper's SUSAN + NCC front end finds and keeps correct matches (most of what RANSAC on F
keeps: a match that slides along its epipolar line passes it), and the truth it is scored against is
the rendered geometry (a keypoint's own projection is where the next frame sees it)."""

from __future__ import annotations

import numpy as np

from experiments.front_ends import FRONT_ENDS, Flight, _truth, compare, fly


def test_each_front_end_is_scored_and_susan_ncc_keeps_mostly_correct_matches():
    flight = fly(seed=1, frames=3, scale=0.5)
    out = compare(flight)
    assert set(out) == set(FRONT_ENDS)
    assert out["susan-ncc"]["correct_matches"] >= 10 and out["susan-ncc"]["correct_share"] >= 0.6
    assert all(0.0 <= row["repeatability"] <= 1.0 for row in out.values())


def test_the_truth_maps_a_pixel_to_where_the_next_frame_sees_the_same_ground():
    one = fly(seed=2, frames=1, scale=0.25)
    flight = Flight(*(np.concatenate([a, a]) for a in (one.frames, one.depth, one.centres, one.rotations)), one.camera)
    width, height = flight.camera.size  # the camera did not move: every pixel stays
    pixels = np.array([[width / 2, height / 2], [10.0, height - 10.0]])
    projected, seen = _truth(flight, 0, pixels)
    assert seen.all()
    np.testing.assert_allclose(projected, pixels, atol=1e-6)
