"""The paper's two-frame triangulation (vehicle.vision.triangulation) against known geometry: exact
points from exact pixels, the covariance's Jacobian against finite differences, the covariance
honest over Monte Carlo pixel noise, the thin ellipsoid of a short baseline, and the cases that must
be refused (a pure rotation, a point behind a camera), and the covariance worked out at a predicted point
(a landmark fused from many sightings weighted by their own covariances drifts short; weighted by the
covariance at the point, it does not); a pure rotation is also what the two-view model
choice takes for a homography, as it takes flat ground (test_visual_odometry)."""

from __future__ import annotations

import numpy as np
import pytest

from bus.statistics import chi2_band
from vehicle.vision.triangulation import camera_matrices, covariance_at, triangulate
from vehicle.vision.two_view import select_model

K = np.array([[1015.78212, 0.0, 320.03704], [0.0, 1012.658, 240.40334], [0.0, 0.0, 1.0]])  # the paper's


def rotation(yaw: float, pitch: float = 0.0) -> np.ndarray:
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    return np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]]) @ np.array(
        [[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]]
    )


def project(m: np.ndarray, X: np.ndarray) -> np.ndarray:
    x = np.column_stack([X, np.ones(len(X))]) @ m.T
    return x[:, :2] / x[:, 2:3]


def scene(rng: np.random.Generator, n: int, depth: tuple[float, float] = (4.0, 12.0)) -> np.ndarray:
    z = rng.uniform(*depth, n)
    return np.column_stack([rng.uniform(-0.3, 0.3, n) * z, rng.uniform(-0.2, 0.2, n) * z, z])


def test_exact_pixels_give_the_points():
    rng = np.random.default_rng(0)
    X = scene(rng, 50)
    m1, m2 = camera_matrices(K, rotation(0.05, 0.02), np.array([-1.0, 0.1, 0.2]))
    out = triangulate(m1, m2, project(m1, X), project(m2, X))
    assert out.usable.all()
    np.testing.assert_allclose(out.points, X, rtol=1e-9)


def test_the_covariance_follows_the_least_squares_solution_to_first_order():
    rng = np.random.default_rng(1)
    X = scene(rng, 5)
    m1, m2 = camera_matrices(K, rotation(0.03), np.array([-0.8, 0.0, 0.1]))
    uv1, uv2 = project(m1, X) + rng.normal(0, 1, (5, 2)), project(m2, X) + rng.normal(0, 1, (5, 2))
    base = triangulate(m1, m2, uv1, uv2)
    step = 1e-5
    columns = []
    for which, coordinate in ((0, 0), (0, 1), (1, 0), (1, 1)):
        moved = [uv1.copy(), uv2.copy()]
        moved[which][:, coordinate] += step
        columns.append((triangulate(m1, m2, *moved).points - base.points) / step)
    J = np.stack(columns, axis=2)  # (n, 3, 4)
    np.testing.assert_allclose(base.covariances, np.einsum("nik,njk->nij", J, J), rtol=1e-4, atol=1e-12)


def test_the_covariance_is_honest_over_pixel_noise():
    rng = np.random.default_rng(2)
    X = np.array([[0.5, -0.3, 6.0]])
    m1, m2 = camera_matrices(K, rotation(0.05), np.array([-1.0, 0.0, 0.0]))
    sigma, draws = 1.0, 2000
    uv1 = project(m1, X) + rng.normal(0, sigma, (draws, 2))
    uv2 = project(m2, X) + rng.normal(0, sigma, (draws, 2))
    out = triangulate(m1, m2, uv1, uv2, sigma_px=sigma)
    error = out.points - X
    nees = np.einsum("ni,nij,nj->n", error, np.linalg.inv(out.covariances), error)
    low, high = chi2_band(3, runs=draws)
    assert out.parallax_rad[0] > np.deg2rad(5)
    assert low <= nees.mean() <= high


def test_a_short_baseline_gives_a_long_thin_ellipsoid_along_the_ray():
    X = np.array([[0.0, 0.0, 8.0]])
    lengths = []
    for baseline in (2.0, 0.5, 0.2):
        m1, m2 = camera_matrices(K, np.eye(3), np.array([-baseline, 0.0, 0.0]))
        out = triangulate(m1, m2, project(m1, X), project(m2, X))
        values, vectors = np.linalg.eigh(out.covariances[0])
        lengths.append(np.sqrt(values[-1]))
        assert abs(vectors[:, -1] @ np.array([0.0, 0.0, 1.0])) > 0.95  # the long axis lies along the ray
        assert values[-1] / values[0] > 20.0
    assert lengths[1] / lengths[0] == pytest.approx(4.0, rel=0.1)  # 1 / parallax: a quarter of the baseline
    assert lengths[2] / lengths[1] == pytest.approx(2.5, rel=0.1)


def test_a_pure_rotation_and_a_point_behind_are_refused_never_returned():
    rng = np.random.default_rng(3)
    X = scene(rng, 30)
    m1, m2 = camera_matrices(K, rotation(0.1, 0.05), np.zeros(3))
    uv1, uv2 = project(m1, X) + rng.normal(0, 0.5, (30, 2)), project(m2, X) + rng.normal(0, 0.5, (30, 2))
    out = triangulate(m1, m2, uv1, uv2)
    assert not out.usable.any()
    assert set(out.refusal) <= {"parallax", "behind"}
    choice = select_model(uv1, uv2, rng)  # the two-view model choice sees a homography too
    assert choice is not None and choice.model == "homography"
    m1, m2 = camera_matrices(K, np.eye(3), np.array([-1.0, 0.0, 0.0]))
    behind = np.array([[0.5, 0.2, -5.0]])
    assert triangulate(m1, m2, project(m1, behind), project(m2, behind)).refusal.tolist() == ["behind"]


def test_the_covariance_at_a_point_is_the_triangulation_s_at_its_exact_pixels():
    X = scene(np.random.default_rng(4), 20, (8.0, 40.0))
    m1, m2 = camera_matrices(K, rotation(0.03, 0.1), np.array([-2.0, 0.1, -0.5]))
    expected = triangulate(m1, m2, project(m1, X), project(m2, X), sigma_px=1.5).covariances
    np.testing.assert_allclose(covariance_at(m1, m2, X, sigma_px=1.5), expected, rtol=1e-9)
    behind = covariance_at(m1, m2, np.array([[0.0, 0.0, -5.0], [0.0, 0.0, 10.0]]))
    assert np.isnan(behind[0]).all() and np.isfinite(behind[1]).all()  # a point behind has none


def fused_depth_errors(weights_at_the_point: bool, trials: int = 1000, sightings: int = 100) -> np.ndarray:
    """A far point (about 2.5 degrees of parallax) fused from ``sightings`` fresh triangulations by
    their information (the EKF's map update for a landmark that stands still), in ``trials`` seeded
    trials: the fused depth's error over its claimed sigma, one per trial."""
    rng = np.random.default_rng(7)
    X = np.array([[1.0, -0.5, 40.0]])
    m1, m2 = camera_matrices(K, np.eye(3), np.array([-1.8, 0.0, 0.0]))
    at_point = covariance_at(m1, m2, X)[0]
    out = []
    for _ in range(trials):
        uv1 = project(m1, X) + rng.normal(0, 1.0, (sightings, 2))
        uv2 = project(m2, X) + rng.normal(0, 1.0, (sightings, 2))
        seen = triangulate(m1, m2, uv1, uv2)
        info = np.linalg.inv(
            np.broadcast_to(at_point, seen.covariances.shape) if weights_at_the_point else seen.covariances
        )
        P = np.linalg.inv(info.sum(axis=0))
        fused = P @ np.einsum("nij,nj->i", info, seen.points)
        out.append((fused[2] - X[0, 2]) / np.sqrt(P[2, 2]))
    return np.array(out)


def test_a_landmark_weighted_by_the_noise_at_its_own_pixels_drifts_short_and_at_the_point_does_not():
    """The depth variance grows as depth^4: a sighting measured short claims a smaller ellipsoid and
    weighs more, so the fused point is short by more than its claimed sigma after 100 sightings. With
    each sighting's covariance worked out at the point (what the back end's ``noise_at`` gives for a
    prediction), the fused error is centred and its spread is what the covariance claims."""
    own = fused_depth_errors(False)
    at_point = fused_depth_errors(True)
    standard_error = 1.0 / np.sqrt(len(own))
    assert own.mean() < -0.5  # short, by over half a claimed sigma on average
    assert abs(at_point.mean()) < 3.5 * standard_error
    low, high = chi2_band(1, runs=len(at_point))
    assert low <= np.mean(at_point**2) <= high
