"""Vehicles without wheels through real processes (lockstep): their speed and yaw rate come from
visual odometry between consecutive camera frames (vehicle.vision.visual_odometry), GNSS jammed all flight.
VO alone drifts within a stated share of the distance travelled and stays consistent; ar-ekf-slam on
the same VO does better."""

import math

import numpy as np
import pytest

from tests.integration.conftest import read_summary, run_swarm

pytestmark = pytest.mark.integration

SCENARIO = """
name = "visual-odometry"
[world]
vehicles = 2
seed = 3
trajectories = ["circle", "circle"]
[clock]
duration_s = 40
[sensors]
camera_rate_hz = 10
prior_sigma_m = 0.1
prior_heading_sigma_rad = 0.005
[vehicle]
estimator = "{estimator}"
odometry = "visual"
[vehicle.cooperation]
enabled = false
[[faults]]
name = "no-gnss"
kind = "jam-gnss"
center_m = [0.0, 0.0]
radius_m = 500.0
"""
DRIFT_PER_METRE = 0.04  # VO alone: the largest position error within 4 % of the distance flown


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = tmp_path_factory.mktemp("vo")
    runs = {}
    for estimator in ("ekf", "ar-ekf-slam"):
        scenario = out / f"{estimator}.toml"
        scenario.write_text(SCENARIO.format(estimator=estimator))
        result = run_swarm(out, str(scenario), "--mode", "lockstep", "--name", estimator, timeout_s=300)
        assert result.returncode == 0, result.stdout + result.stderr
        runs[estimator] = out / estimator
    return runs


def distance_flown(run, vehicle: int) -> float:
    xy = np.loadtxt(run / "tum" / f"truth_v{vehicle}.tum")[:, 1:3]
    return float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))


def test_visual_odometry_alone_drifts_within_its_share_of_the_distance_and_stays_consistent(runs):
    summary = read_summary(runs["ekf"])
    assert summary["status"] == "complete"
    for vid in (1, 2):
        vehicle, flown = summary["vehicles"][str(vid)], distance_flown(runs["ekf"], vid)
        assert flown > 150
        assert vehicle["max_error_m"] < DRIFT_PER_METRE * flown, (vid, vehicle["max_error_m"], flown)
        assert 1.0 < vehicle["anees"] < 6.0, vehicle["anees"]  # 3 dof; one run's NEES is correlated in time


def test_slam_on_visual_odometry_beats_visual_odometry_alone(runs):
    alone, slam = read_summary(runs["ekf"])["vehicles"], read_summary(runs["ar-ekf-slam"])["vehicles"]
    for vid in ("1", "2"):
        assert slam[vid]["rmse_m"] < 0.85 * alone[vid]["rmse_m"], (vid, slam[vid]["rmse_m"], alone[vid]["rmse_m"])
        assert math.isfinite(slam[vid]["anees"]) and slam[vid]["anees"] < 6.0


def test_frame_pairs_without_a_motion_are_counted_and_the_loop_goes_on(runs):
    """Over this terrain an 80 px frame holds 10 to 25 keypoints: some pairs share too few."""
    summary = read_summary(runs["ekf"])
    failed = summary["rejected"]["by_reason"].get("no_visual_motion", 0)
    assert 0 < failed < 0.5 * 2 * 400
    assert summary["vehicles"]["1"]["samples"] == summary["vehicles"]["2"]["samples"] > 0
