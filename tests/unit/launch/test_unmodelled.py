"""The unmodelled sigma (launch.unmodelled): the sigma that, added to every position variance, brings the
pooled position NEES to 2; found where errors carry a part no covariance covers, none where the
covariances already cover them; and the simulated world refuses one (it has no such error)."""

import numpy as np
import pytest

from bus.config import build_config
from bus.errors import ConfigError
from bus.statistics import published_pose_cov
from launch.unmodelled import unmodelled_sigma


def test_the_sigma_is_the_part_of_the_error_no_covariance_covers():
    rng = np.random.default_rng(0)
    k, claimed, unseen = 20_000, 0.01, 0.03
    covariances = np.broadcast_to(np.eye(2) * claimed**2, (k, 2, 2))
    errors = rng.normal(0, claimed, (k, 2)) + rng.normal(0, unseen, (k, 2))
    assert unmodelled_sigma(errors, covariances) == pytest.approx(unseen, rel=0.03)


def test_none_where_the_covariances_cover_the_errors():
    rng = np.random.default_rng(1)
    covariances = np.broadcast_to(np.eye(2) * 0.05**2, (5_000, 2, 2))
    assert unmodelled_sigma(rng.normal(0, 0.04, (5_000, 2)), covariances) == 0.0
    assert unmodelled_sigma(np.zeros((0, 2)), np.zeros((0, 2, 2))) == 0.0


def test_the_published_covariance_carries_it_on_position_only():
    cov = np.diag([1e-4, 4e-4, 1e-3])
    out = published_pose_cov(cov, 0.02)
    assert np.allclose(np.diag(out), [1e-4 + 4e-4, 4e-4 + 4e-4, 1e-3]) and out is not cov
    assert published_pose_cov(cov, 0.0) is cov


def test_a_simulated_swarm_refuses_one():
    with pytest.raises(ConfigError, match="unmodelled_sigma_m"):
        build_config({"sensors": {"unmodelled_sigma_m": 0.02}})
