"""The common mode and the relative part of a swarm's errors: honest errors give each part its
chi-square mean; an offset shared by every vehicle shows in the centroid alone."""

import numpy as np
from scipy.stats import chi2

from experiments.swarm_modes import swarm_modes

VEHICLES, DRAWS = 6, 400


def _joint_covariance(rng: np.random.Generator) -> np.ndarray:
    """A correlated (3N, 3N) covariance, pose units [m, m, rad]: vehicles tied by shared history."""
    scale = np.tile([0.3, 0.3, 0.01], VEHICLES)
    mixing = rng.normal(size=(3 * VEHICLES, 3 * VEHICLES)) + 2.0 * np.kron(np.ones((VEHICLES, VEHICLES)), np.eye(3))
    root = mixing * scale[:, None]
    return root @ root.T + np.diag((0.05 * scale) ** 2)


def _band(dof: int) -> tuple[float, float]:
    return tuple(chi2.ppf([0.0005, 0.9995], dof * DRAWS) / DRAWS)


def test_honest_errors_give_each_part_its_degrees_of_freedom():
    rng = np.random.default_rng(7)
    covariance = _joint_covariance(rng)
    draws = rng.multivariate_normal(np.zeros(3 * VEHICLES), covariance, size=DRAWS)
    modes = [swarm_modes(d.reshape(VEHICLES, 3), covariance) for d in draws]
    assert {m.relative_dof for m in modes} == {3 * VEHICLES - 3}
    for dof, values in ((2, [m.centroid_nees for m in modes]), (1, [m.heading_nees for m in modes])):
        low, high = _band(dof)
        assert low < np.mean(values) < high, (dof, np.mean(values), low, high)
    low, high = _band(3 * VEHICLES - 3)
    assert low < np.mean([m.relative_nees for m in modes]) < high


def test_an_offset_every_vehicle_shares_is_the_centroids_alone():
    rng = np.random.default_rng(8)
    covariance = _joint_covariance(rng)
    draw = rng.multivariate_normal(np.zeros(3 * VEHICLES), covariance).reshape(VEHICLES, 3)
    honest = swarm_modes(draw, covariance)
    shifted = swarm_modes(draw + np.array([20.0, -20.0, 0.0]), covariance)
    assert shifted.centroid_nees > 20 * max(honest.centroid_nees, 1.0)
    assert np.isclose(shifted.relative_nees, honest.relative_nees)
    assert np.isclose(shifted.heading_nees, honest.heading_nees)
    assert np.isclose(shifted.centroid_error_m, np.hypot(*(draw[:, :2].mean(axis=0) + [20.0, -20.0])))
