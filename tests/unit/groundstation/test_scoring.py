"""Scoring against truth: interpolation, NEES, ordering, and RMSE."""

import numpy as np
import pytest

from bus.mavlink_codec import StateEstimate
from groundstation.scoring import Scorer, score, score_all
from groundstation.truth_track import TruthTrack


def _est(vid: int, t_us: int, x: float, y: float, yaw: float = 0.0, var: float = 1.0) -> StateEstimate:
    cov = np.diag([var, var, 1e-6, 1e-6, 1e-6, var])
    return StateEstimate(vid, t_us, np.array([x, y, -30.0]), yaw, np.zeros(3), 0.0, cov, np.eye(6))


def test_truth_interpolation_is_angle_aware():
    track = TruthTrack()
    track.add(0, np.array([0.0, 0.0, np.pi - 0.1]))
    track.add(100, np.array([10.0, 0.0, -np.pi + 0.1]))
    pose = track.at(50)
    assert pose[0] == pytest.approx(5.0)
    assert abs(abs(pose[2]) - np.pi) < 1e-9


def test_nees_of_a_known_error():
    result = score(_est(1, 0, 3.0, 4.0, var=4.0), np.array([0.0, 0.0, 0.0]))
    assert result.position_error_m == pytest.approx(5.0)
    assert result.nees == pytest.approx(25.0 / 4.0)


def _random_estimates(rng: np.random.Generator, n: int) -> tuple[list[StateEstimate], list[np.ndarray]]:
    ests, truths = [], []
    for k in range(n):
        a = rng.normal(size=(6, 6)) * rng.uniform(1e-3, 10)
        yaw, true_yaw = rng.uniform(-np.pi, np.pi, 2)  # errors across the wrap too
        ests.append(StateEstimate(k % 7, k, rng.normal(size=3) * 100, yaw, np.zeros(3), 0.0, a @ a.T, np.eye(6), k % 3))
        height = rng.normal() * 10 if k % 3 else np.nan  # no height known for every third
        truths.append(np.array([*rng.normal(size=2) * 100, true_yaw, height]))
    return ests, truths


def test_scoring_many_at_once_gives_each_score_to_the_bit():
    ests, truths = _random_estimates(np.random.default_rng(7), 300)
    for one, together in zip([score(e, t) for e, t in zip(ests, truths)], score_all(ests, truths), strict=True):
        assert together.nees == one.nees and together.reset_counter == one.reset_counter
        assert together.error_m.tobytes() == one.error_m.tobytes()
        assert together.pose_covariance.tobytes() == one.pose_covariance.tobytes()
        assert together.estimate is one.estimate and together.truth_pose.tobytes() == one.truth_pose.tobytes()
        assert together.sigma.tobytes() == one.sigma.tobytes()  # worked out for all at once
        assert repr(together.position_error_m) == repr(one.position_error_m)
        assert type(together.position_error_m) is float
        assert repr(together.altitude_error_m) == repr(one.altitude_error_m)
        assert repr(together.altitude_nees) == repr(one.altitude_nees)


def test_a_singular_covariance_leaves_only_its_estimate_unscored():
    ests, truths = _random_estimates(np.random.default_rng(8), 5)
    singular = StateEstimate(9, 2, np.zeros(3), 0.0, np.zeros(3), 0.0, np.zeros((6, 6)), np.eye(6))
    ests.insert(2, singular)
    truths.insert(2, np.zeros(4))
    scores = score_all(ests, truths)
    assert scores[2] is None and all(s is not None for i, s in enumerate(scores) if i != 2)
    assert [s.nees for s in scores if s is not None] == [
        score(e, t).nees for e, t in zip(ests, truths) if e is not singular
    ]
    scorer = Scorer()
    for e, t in zip(ests, truths):
        scorer.add_truth(e.vehicle_id, e.time_usec, t)
        scorer.add_estimate(e)
    assert len(scorer.release(float("inf"))) == 5 and scorer.unscored == 1


def test_release_orders_by_time_then_vehicle_and_waits_for_truth():
    scorer = Scorer()
    for vid in (2, 1):
        for t in (0, 20_000):
            scorer.add_truth(vid, t, np.zeros(3))
    for est in (_est(2, 20_000, 1, 0), _est(1, 20_000, 2, 0), _est(2, 0, 3, 0), _est(1, 40_000, 4, 0)):
        scorer.add_estimate(est)
    released = scorer.release(20_000)
    assert [(s.stamp_us, s.vehicle_id) for s in released] == [(0, 2), (20_000, 1), (20_000, 2)]
    assert len(scorer.pending) == 1
    assert scorer.release(float("inf")) == [] and scorer.unscored == 1  # no truth at 40 ms


def test_rmse_tally():
    scorer = Scorer()
    for t in (0, 1, 2):
        scorer.add_truth(1, t, np.zeros(3))
    for t, x in ((0, 3.0), (1, 4.0), (2, 0.0)):
        scorer.add_estimate(_est(1, t, x, 0.0))
    scorer.release(float("inf"))
    tally = scorer.tallies[1]
    assert np.sqrt(tally.sum_sq_position_m2 / tally.samples) == pytest.approx(np.sqrt(25 / 3))
    assert tally.max_position_error_m == 4.0


def test_a_degenerate_covariance_is_never_fatal_and_the_backlog_is_bounded(monkeypatch):
    import groundstation.scoring as scoring

    scorer = Scorer()
    scorer.add_truth(1, 0, np.zeros(3))
    scorer.add_estimate(_est(1, 0, 1.0, 0.0, var=0.0))  # the intake rejects these; scoring survives them anyway
    assert scorer.release(float("inf")) == [] and scorer.unscored == 1
    monkeypatch.setattr(scoring, "MAX_PENDING", 3)
    accepted = [scorer.add_estimate(_est(1, t, 0.0, 0.0)) for t in (10, 20, 30, 40, 50)]
    assert accepted == [True, True, True, False, False] and scorer.dropped_full == 2


def test_estimates_where_truth_has_a_gap_are_counted_not_scored():
    """A replayed data set's Vicon gap arrives as NaN truth: no interpolation across it."""
    scorer = Scorer()
    for t, pose in ((0, np.zeros(3)), (20, np.full(3, np.nan)), (40, np.full(3, np.nan)), (60, np.zeros(3))):
        scorer.add_truth(1, t, pose)
    for t in (0, 10, 30, 50, 60):
        scorer.add_estimate(_est(1, t, 1.0, 0.0))
    scored = scorer.release(float("inf"))
    assert [s.stamp_us for s in scored] == [0, 60] and scorer.in_truth_gaps == 3 and scorer.unscored == 0


def test_a_vehicle_that_estimates_its_height_is_scored_on_it_and_a_level_one_is_not():
    """A UAV's ODOMETRY carries its height above the launch point (z, with its own variance); the
    ground station scores it against the truth's height, apart from the planar pose, and the summary
    says so for that vehicle only. A vehicle that flies level (z's variance NOT_ESTIMATED_VAR) has no
    height score, however its z differs from the truth's."""
    from bus.config import build_config
    from groundstation.summary import build_summary

    scorer = Scorer()
    uav_cov = np.diag([1.0, 1.0, 0.25, 1e-6, 1e-6, 1.0])
    for k, t_us in enumerate(range(0, 3_000_000, 100_000)):
        truth_height = 0.1 * k
        scorer.add_truth(1, t_us, np.array([0.0, 0.0, 0.0, truth_height]))
        scorer.add_truth(2, t_us, np.array([0.0, 0.0, 0.0, 0.0]))
        uav = StateEstimate(
            1, t_us, np.array([0.0, 0.0, -(truth_height + 1.0)]), 0.0, np.zeros(3), 0.0, uav_cov, np.eye(6)
        )
        scorer.add_estimate(uav)
        scorer.add_estimate(_est(2, t_us, 0.0, 0.0))  # z = -30 against a height of 0
    scores = scorer.release(float("inf"))
    uav = [s for s in scores if s.vehicle_id == 1]
    assert all(s.altitude_error_m == pytest.approx(1.0) and s.altitude_nees == pytest.approx(4.0) for s in uav)
    assert all(np.isnan(s.altitude_nees) for s in scores if s.vehicle_id == 2)
    assert scorer.tallies[2].altitude is None
    summary = build_summary(build_config({"world": {"vehicles": 2}}), scorer, {}, {}, "complete")
    height = summary["vehicles"]["1"]["altitude"]
    assert height["samples"] == 30 and height["rmse_m"] == pytest.approx(1.0) and height["anees"] == pytest.approx(4.0)
    assert height["nees_dof"] == 1 and height["consistency"]["block_anees"] == pytest.approx(4.0)
    assert height["consistency"]["band_95"][1] == pytest.approx(5.024, abs=1e-3)  # one block of 1 dof
    assert "altitude" not in summary["vehicles"]["2"]
