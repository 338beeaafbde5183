"""A flat-ground map's points (experiments.flat_ground): exact on the plane it assumes, wrong by what
the plane misses, and with the covariance its pixels' noise gives."""

from __future__ import annotations

import numpy as np
import pytest

from bus.sensors.camera3d import PAPER_K, look
from experiments.ar_slam3d import fly
from experiments.flat_ground import flat_ground_points
from sim.pinhole import PAPER_SIZE, Pinhole

CAMERA = Pinhole(PAPER_K, PAPER_SIZE)
C = np.array([3.0, -2.0, 15.0])
R_WC = look(0.4, np.deg2rad(30.0))


def _on_ground(rng: np.random.Generator, n: int, height: float = 0.0) -> np.ndarray:
    """Points n (n, 3) on the plane z = ``height`` ahead of the camera, most of them in view."""
    ahead = rng.uniform(15.0, 45.0, n)
    across = rng.uniform(-8.0, 8.0, n)
    forward, side = np.array([np.cos(0.4), np.sin(0.4)]), np.array([-np.sin(0.4), np.cos(0.4)])
    xy = C[:2] + ahead[:, None] * forward + across[:, None] * side
    return np.column_stack([xy, np.full(n, height)])


def test_on_the_plane_it_assumes_a_point_is_where_it_lies():
    landmarks = _on_ground(np.random.default_rng(1), 40)
    points, _, index = flat_ground_points(
        CAMERA, landmarks, C, R_WC, 15.0, 60.0, np.random.default_rng(2), sigma_px=0.0
    )
    assert len(index) > 20
    np.testing.assert_allclose(points, (landmarks[index] - C) @ R_WC, atol=1e-9)


def test_a_landmark_above_the_plane_is_placed_beyond_it_along_its_ray():
    landmarks = _on_ground(np.random.default_rng(3), 20, height=3.0)  # 3 m above the assumed ground
    points, _, index = flat_ground_points(
        CAMERA, landmarks, C, R_WC, 15.0, 90.0, np.random.default_rng(4), sigma_px=0.0
    )
    true = (landmarks[index] - C) @ R_WC
    np.testing.assert_allclose(np.linalg.norm(points, axis=1) / np.linalg.norm(true, axis=1), 15.0 / 12.0, rtol=1e-9)


@pytest.mark.parametrize("height_sigma_m", [0.0, 0.5])
def test_its_covariance_is_the_spread_of_its_pixels_and_heights_noise(height_sigma_m):
    landmark = _on_ground(np.random.default_rng(5), 1)
    rng = np.random.default_rng(6)
    draws, predicted = [], None
    for _ in range(3000):
        height = 15.0 + rng.normal(0.0, height_sigma_m)  # the true plane; the model assumes 15 m
        point, covariance, index = flat_ground_points(
            CAMERA,
            landmark * [1, 1, 0] + [0, 0, 15.0 - height],
            C,
            R_WC,
            15.0,
            90.0,
            rng,
            height_sigma_m=height_sigma_m,
        )
        assert len(index) == 1
        draws.append(point[0])
        predicted = covariance[0] if predicted is None else predicted
    spread = np.cov(np.array(draws).T)
    assert np.linalg.matrix_rank(predicted, tol=1e-9 * np.abs(predicted).max()) == (
        3 if height_sigma_m else 2
    )  # the plane fixes one direction
    # along the three axes the spread matches the first-order covariance within Monte Carlo's 10 %
    for axis in np.linalg.eigh(spread + predicted)[1].T:
        assert axis @ spread @ axis == pytest.approx(axis @ predicted @ axis, rel=0.1)


def test_over_relief_a_flat_ground_map_loses_the_vehicle_where_triangulation_keeps_it():
    """The same 60 frames (30 m) over the hills, the same back end: only where the points come from differs."""

    def final_error_m(**options) -> float:
        track = fly(0, 60, "adaptive", **options)
        return float(np.linalg.norm((track.estimate - track.truth)[-1, :2]))

    assert final_error_m(flat_ground=True) > 2.0
    assert final_error_m(flat_ground=False) < 0.5
    assert final_error_m(flat_ground=True, relief=False) < 1.0  # over flat ground its assumption holds
