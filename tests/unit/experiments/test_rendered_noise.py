"""The rendered front end's noise against the truth (experiments.rendered_noise): the
truth's projection is exact where it can be checked, and the corners followed over ten frames land
within a pixel of where the ground they saw projects, so the 1 px the triangulation was told is too much."""

import numpy as np

from experiments.ar_slam3d_rendered import flight
from experiments.rendered_noise import bilinear, flight_errors, projected
from sim.pinhole import render


def test_bilinear_interpolation_is_exact_on_a_plane():
    rows, cols = np.mgrid[0:6, 0:8].astype(float)
    plane = 2.0 * cols - 3.0 * rows + 1.0
    pixels = np.array([[1.25, 2.5], [6.9, 4.1], [3.0, 3.0]])
    assert np.allclose(bilinear(plane, pixels), 2.0 * pixels[:, 0] - 3.0 * pixels[:, 1] + 1.0)


def test_the_ground_seen_at_a_pixel_projects_back_onto_it_and_moves_with_the_camera():
    path = flight(0, 12)
    _, depth = render(path.relief, path.camera, path.positions[0], path.rotations[0], np.random.default_rng(0))
    pixels = np.array([[100.0, 150.0], [200.5, 180.25], [160.0, 200.0]])
    assert np.allclose(projected(path, depth, 0, 0, pixels), pixels, atol=1e-6)
    later = projected(path, depth, 0, 10, pixels)
    assert np.linalg.norm(later - pixels, axis=1).min() > 5.0  # 5 m on, the ground has moved in the frame


def test_corners_followed_over_ten_frames_land_within_a_pixel_of_the_truth():
    errors, directions = flight_errors(100, 25)  # a flight of the fitting seeds, never scored
    assert len(errors) > 200 and directions.shape == (16, 2)
    assert np.sqrt(np.mean(errors**2)) < 1.0 and (np.linalg.norm(errors, axis=1) > 3.0).mean() < 0.01
    assert np.abs(directions).max() < np.deg2rad(1.0)  # the direction of travel fitted within a degree


def test_the_papers_visual_odometry_is_exact_on_exact_correspondences_and_loses_degrees_to_a_third_of_a_pixel():
    from experiments.rendered_noise import two_view_errors

    rotation, direction = two_view_errors(100, 0.0, pairs=3, draws=1)
    assert len(rotation) == 3 and rotation.max() < 0.01 and direction.max() < 0.01
    rotation, direction = two_view_errors(100, 0.33, pairs=3, draws=3)
    assert np.median(direction) > 1.0  # 40 points, 35 degrees of view, 5 m forward: ill-posed
