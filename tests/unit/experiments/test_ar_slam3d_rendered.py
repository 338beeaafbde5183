"""The paper's whole 3-D system on rendered frames (experiments.ar_slam3d_rendered): the frames are
rendered by ray casting, the SUSAN + NCC front end matches them, the matched corners are triangulated
and mapped with no landmark ids, and the vehicle is located from them."""

from __future__ import annotations

import numpy as np

from experiments.ar_slam3d_rendered import fly

TOLD = np.array([0.009, 0.009, 0.0016])  # about what motion_noise() fits (fitting takes half a minute)


def test_rendered_frames_are_matched_triangulated_and_mapped_and_locate_the_vehicle():
    track, counts = fly(0, 40, "adaptive", rotation="given", omega_var=TOLD)
    assert counts.failed == 0 and counts.points / 40 > 10  # each frame gives points from its corners
    assert track.landmarks.max() > 20 and np.isnan(track.landmark_nees).all()  # mapped, no identities
    error = np.linalg.norm(track.estimate - track.truth, axis=1)
    assert error.max() < 1.0  # 20 m flown on a 60 m circle: constant velocity alone is 3 m off after 4 s
    assert np.isfinite(track.position_nees()).all()


def test_a_second_triangulation_confirms_a_point_only_within_their_covariances():
    from experiments.ar_slam3d_rendered import refereed

    z = np.array([[0.0, 0.0, 20.0], [1.0, 0.0, 20.0], [2.0, 0.0, 20.0]])
    cov = np.tile(np.diag([0.01, 0.01, 1.0]), (3, 1, 1))  # long along the ray
    corners = np.array([4, 7, 9])
    other = np.array([[0.0, 0.0, 21.0], [2.0, 0.0, 20.0], [np.nan, np.nan, np.nan]])
    # corner 4: 1 m along the ray (confirmed); corner 7: 1 m across it (not); corner 9: refused there
    assert refereed(z, cov, corners, other, cov, np.array([4, 7, 9])).tolist() == [True, False, False]
    assert not refereed(z, cov, corners, other, cov, np.array([1, 2, 3])).any()  # not triangulated there
