"""The paper's whole 3-D system on rendered frames (experiments.ar_slam3d_rendered): the frames are
rendered by ray casting, the SUSAN + NCC front end matches them, the matched corners are triangulated
and mapped with no landmark ids, and the vehicle is located from them."""

from __future__ import annotations

import numpy as np

from experiments.ar_slam3d_rendered import fly

TOLD = np.array([0.009, 0.009, 0.0016])  # about what motion_noise() fits (fitting takes half a minute)


def test_rendered_frames_are_matched_triangulated_and_mapped_and_locate_the_vehicle():
    track, counts = fly(0, 40, "adaptive", rotation="given", omega_var=TOLD, pitch_deg=30.0)
    assert counts.failed == 0 and counts.points / 40 > 10  # each frame gives points from its corners
    assert track.landmarks.max() > 20 and np.isnan(track.landmark_nees).all()  # mapped, no identities
    error = np.linalg.norm(track.estimate - track.truth, axis=1)
    assert error.max() < 1.0  # 20 m flown on a 60 m circle: constant velocity alone is 3 m off after 4 s
    assert np.isfinite(track.position_nees()).all()


def test_a_second_triangulation_confirms_a_point_only_within_their_covariances():
    from experiments.rendered_front_end import refereed

    z = np.array([[0.0, 0.0, 20.0], [1.0, 0.0, 20.0], [2.0, 0.0, 20.0]])
    cov = np.tile(np.diag([0.01, 0.01, 1.0]), (3, 1, 1))  # long along the ray
    corners = np.array([4, 7, 9])
    other = np.array([[0.0, 0.0, 21.0], [2.0, 0.0, 20.0], [np.nan, np.nan, np.nan]])
    # corner 4: 1 m along the ray (confirmed); corner 7: 1 m across it (not); corner 9: refused there
    assert refereed(z, cov, corners, other, cov, np.array([4, 7, 9])).tolist() == [True, False, False]
    assert not refereed(z, cov, corners, other, cov, np.array([1, 2, 3])).any()  # not triangulated there


def test_corners_followed_frame_to_frame_pair_the_same_ground_where_ncc_across_the_baseline_does_not():
    from experiments.ar_slam3d_rendered import flight
    from experiments.rendered_noise import projected
    from sim.pinhole import render
    from vehicle.vision import ncc, susan
    from vehicle.vision.corner_tracks import CornerTracks

    path, rng, tracks = flight(0, 31), np.random.default_rng(1), CornerTracks()
    frames = {}
    for k in range(20, 31):
        image, depth = render(path.relief, path.camera, path.positions[k], path.rotations[k], rng)
        frames[k] = (image, depth, susan.corners(image)[0])
        tracks.step(k, image, frames[k][2])
    (image_j, depth_j, corners_j), (image_k, _, corners_k) = frames[20], frames[30]
    p1, p2, _ = tracks.pairs(20, 30)
    followed = np.linalg.norm(projected(path, depth_j, 20, 30, p1) - p2, axis=1)
    i1, i2, _ = ncc.match(image_j, corners_j, image_k, corners_k)
    matched = np.linalg.norm(projected(path, depth_j, 20, 30, corners_j[i1]) - corners_k[i2], axis=1)
    assert len(p1) >= 40 and (followed < 2.0).mean() >= 0.9 and (followed > 5.0).mean() <= 0.02
    assert (matched < 2.0).mean() <= 0.6  # the paper's matching across 5 m of forward flight


def test_the_tracked_front_end_locates_the_vehicle_on_rendered_frames():
    track, counts = fly(0, 40, "adaptive", rotation="given", omega_var=TOLD, tracked=True)
    assert counts.failed == 0 and counts.points / 40 > 20
    error = np.linalg.norm(track.estimate - track.truth, axis=1)
    assert error.max() < 1.0 and np.isfinite(track.position_nees()).all()


def test_where_the_baseline_finds_no_geometry_the_shorter_fallback_gives_the_frame_its_points(monkeypatch):
    from vehicle.vision.corner_tracks import CornerTracks

    followed = CornerTracks.pairs

    def short_lived(tracks, j, k):  # as over close, poor ground: no track lives more than five frames
        p1, p2, ids = followed(tracks, j, k)
        return (p1, p2, ids) if k - j <= 5 else (p1[:0], p2[:0], ids[:0])

    monkeypatch.setattr(CornerTracks, "pairs", short_lived)
    _, alone = fly(0, 14, "adaptive", rotation="given", omega_var=TOLD, tracked=True)
    track, counts = fly(0, 14, "adaptive", rotation="given", omega_var=TOLD, tracked=True, fallback_frames=5)
    assert alone.failed == 9 and counts.failed == 0  # frames 6-14: none without, every one with it
    assert counts.points > alone.points and np.linalg.norm(track.estimate - track.truth, axis=1).max() < 1.0
