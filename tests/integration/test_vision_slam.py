"""Camera vehicles through real processes (lockstep): the world renders each vehicle's frames from
the terrain and publishes them in its sensor batches; `ekf-slam` vehicles with GNSS jammed for the
whole run map the ground, close the loop, and beat dead reckoning flown on the same seed."""

import csv
import math

import pytest

from tests.integration.conftest import read_summary, run_swarm

pytestmark = pytest.mark.integration
SCENARIO = """
name = "{name}"
[world]
vehicles = 2
seed = 3
trajectories = ["circle", "figure8"]
[clock]
duration_s = 60
[sensors]
camera_rate_hz = 10
[vehicle]
estimator = "{estimator}"
cooperative = false
[[faults]]
name = "no-gnss"
kind = "jam-gnss"
center_m = [0.0, 0.0]
radius_m = 1000.0
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    out = {}
    for name, estimator in (("slam", "ekf-slam"), ("dr", "ekf")):
        where = tmp_path_factory.mktemp(name)
        (where / f"{name}.toml").write_text(SCENARIO.format(name=name, estimator=estimator))
        result = run_swarm(where, str(where / f"{name}.toml"))
        assert result.returncode == 0, result.stdout + result.stderr
        out[name] = where / name
    return out


def _sigma_xy(run, vehicle: int) -> dict[float, float]:
    with (run / "metrics.csv").open() as handle:
        return {float(r["t_s"]): math.hypot(float(r["sigma_x_m"]), float(r["sigma_y_m"]))
                for r in csv.DictReader(handle) if r["vehicle"] == str(vehicle)}


def test_camera_vehicles_map_the_ground_they_fly_over(runs):
    summary = read_summary(runs["slam"])
    assert summary["status"] == "complete"
    for vid in ("1", "2"):
        vehicle = summary["vehicles"][vid]
        assert vehicle["samples"] == 60 * 50 + 1
        assert vehicle["camera_frames_used"] == 60 * 10 + 1 and vehicle["landmarks"] >= 50
    assert "garbage_frame" not in summary["rejected"]["by_reason"]


def test_the_loop_closure_shrinks_the_pose_covariance(runs):
    """The circle (vehicle 1) comes back over its start after ~31 s, with no GNSS at all."""
    sigma = _sigma_xy(runs["slam"], 1)
    grown = max(s for t, s in sigma.items() if 20.0 <= t <= 29.0)
    closed = min(s for t, s in sigma.items() if 30.0 <= t <= 33.0)
    assert closed < 0.6 * grown


def test_slam_beats_dead_reckoning_on_the_same_seed(runs):
    slam, dr = read_summary(runs["slam"])["swarm"], read_summary(runs["dr"])["swarm"]
    assert slam["rmse_m"] < dr["rmse_m"]  # 0.27-0.93 of it over 6 seeds at 60 s: the launch heading error is unobservable
