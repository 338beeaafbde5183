"""Data association (vehicle.association): the joint test grown pair by pair equals the batch one; the
paper's tie-break; on repetitive ground (a jittered grid of look-alike landmarks, the pose off by a
draw of its own covariance) joint compatibility and the ant colony find more true pairs and make
fewer false ones than nearest neighbour; the linear optimum is a lower bound of every method's cost."""

import numpy as np
import pytest

from experiments.point_scenes import SceneSpec, correct_rate, scene
from tests.unit.vehicle.association.oracle import grown_as_batch
from vehicle.association.methods import METHODS
from vehicle.association.problem import linear_cost, pairs_of, problem

REPETITIVE = SceneSpec(period_m=1.2, view_m=3.0, pose_sigma_m=0.35)


def test_the_joint_test_grown_pair_by_pair_is_the_batch_one_even_when_the_pose_error_dominates():
    p = scene(np.random.default_rng(3), REPETITIVE).problem
    assignment = METHODS["nn"](p, np.random.default_rng(0))
    assert len(pairs_of(assignment)[0]) >= 10
    grown_as_batch(p, assignment)


def test_nearest_neighbour_breaks_ties_by_the_smaller_innovation_covariance():
    # one observation, two landmarks at the same Mahalanobis distance; the second better known
    C = np.diag([0.5, 0.5, 0.05, 0.05])
    R = np.zeros((1, 2, 2))
    z = np.array([[5.0, 0.0]])
    predicted = np.array([[5.0 - np.sqrt(0.5), 0.0], [5.0 - np.sqrt(0.05), 0.0]])
    p = problem(z, R + 1e-9 * np.eye(2), predicted, C)
    assert p.d2[0, 0] == pytest.approx(p.d2[0, 1])
    assert METHODS["nn"](p, np.random.default_rng(0)).tolist() == [1]


@pytest.mark.parametrize("name", ["nn", "jcbb", "aco", "optimum"])
def test_no_observation_or_no_landmark_is_an_empty_assignment(name):
    empty = problem(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.zeros((3, 2)), np.eye(6))
    assert METHODS[name](empty, np.random.default_rng(0)).shape == (0,)
    lonely = problem(np.array([[3.0, 0.1]]), np.eye(2)[None] * 0.01, np.zeros((0, 2)), np.zeros((0, 0)))
    assert METHODS[name](lonely, np.random.default_rng(0)).tolist() == [-1]


def test_on_repetitive_ground_jcbb_and_the_ant_colony_beat_nearest_neighbour():
    runs = 30
    found = {name: [] for name in METHODS}
    false = {name: [] for name in METHODS}
    for seed in range(runs):
        s = scene(np.random.default_rng(seed), REPETITIVE)
        costs = {}
        for name, method in METHODS.items():
            assignment = method(s.problem, np.random.default_rng(1000 + seed))
            rate, wrong = correct_rate(assignment, s.truth)
            found[name].append(rate)
            false[name].append(wrong)
            costs[name] = linear_cost(s.problem, assignment)
        assert all(cost >= costs["optimum"] - 1e-9 for cost in costs.values())  # the optimum is a lower bound
    rate = {name: float(np.mean(v)) for name, v in found.items()}
    wrong = {name: float(np.mean(v)) for name, v in false.items()}
    assert rate["jcbb"] >= rate["nn"] and rate["aco"] >= rate["nn"], rate
    assert wrong["jcbb"] < 0.5 * wrong["nn"] and wrong["aco"] < 0.5 * wrong["nn"], wrong
