"""3-D AR-EKF-SLAM through the real processes (lockstep): two UAVs of scenarios/uav-3d.toml, their
GNSS jammed, one camera blacked out for a while and a fifth of the other's tracked points lost on
the way, map the points their cameras track, publish estimates the ground station scores for the
whole flight (their heights above the launch point too), and come back onto GNSS after the jam."""

import csv
import json
import math

import numpy as np
import pytest

from tests.integration.conftest import ESTIMATES_PER_S, read_summary, run_swarm

pytestmark = pytest.mark.integration

SCENARIO = """
[world]
vehicles = 2
seed = 2

[clock]
duration_s = 30

[vehicle]
estimator = "ar-ekf-slam-3d"

[sensors.camera3d]
rate_hz = 10

[[faults]]
name = "jammer"
kind = "jam-gnss"
center_m = [0.0, 0.0]
radius_m = 500.0
start_s = 8.0
for_s = 14.0

[[faults]]
name = "camera-out"
kind = "blackout"
vehicle = 1
sensor = "camera3d"
start_s = 12.0
for_s = 3.0

[[faults]]
name = "points-lost"
kind = "loss"
percent = 20.0
dst = "v2"
topic = "camera3d"
start_s = 5.0
for_s = 20.0
"""


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    out = tmp_path_factory.mktemp("uav3d")
    scenario = out / "uav.toml"
    scenario.write_text(SCENARIO)
    result = run_swarm(out, str(scenario), "--mode", "lockstep", "--name", "uav", timeout_s=400)
    assert result.returncode == 0, result.stdout + result.stderr
    return out / "uav"


def _errors(run, vehicle: int) -> dict[float, float]:
    with (run / "metrics.csv").open() as handle:
        return {
            float(r["t_s"]): math.hypot(float(r["err_x_m"]), float(r["err_y_m"]))
            for r in csv.DictReader(handle)
            if r["vehicle"] == str(vehicle)
        }


def test_every_uav_is_scored_for_the_whole_flight(flight):
    summary = read_summary(flight)
    assert summary["status"] == "complete" and summary["faults"]["total"] == 3
    for vid in ("1", "2"):
        vehicle = summary["vehicles"][vid]
        assert vehicle["samples"] == 30 * ESTIMATES_PER_S + 1
        assert vehicle["landmarks"] > 0 and vehicle["decode_errors"] == 0
        assert vehicle["consistency"]["inside"], vehicle["consistency"]  # position and heading, two-sided
    assert summary["vehicles"]["1"]["camera_frames_used"] < summary["vehicles"]["2"]["camera_frames_used"]
    assert summary["vehicles"]["2"]["sensor_samples_lost"] > 0 == summary["vehicles"]["1"]["sensor_samples_lost"]


def test_the_ground_station_scores_each_uavs_height_and_each_claims_it_honestly(flight):
    """GNSS is horizontal and nothing measures the height absolutely: it is carried from the launch
    point by the camera's triangulations alone, and what each UAV claims of it is scored. The one
    blacked out for 3 s comes back unsure by a couple of metres, pairs its points with the map again
    and keeps its height within 3 m too (before the motion model was fitted, it set aside every
    pairing for 9 s and was 8.1 m off at worst: docs/decisions/ar-slam3d-processes.md)."""
    vehicles = read_summary(flight)["vehicles"]
    for vid in ("1", "2"):
        height = vehicles[vid]["altitude"]
        assert height["samples"] == 30 * ESTIMATES_PER_S + 1
        assert height["max_error_m"] < 3.0, height
        assert height["consistency"]["inside"], height["consistency"]  # two-sided, 1 dof


def test_the_map_carries_the_uavs_through_the_jam_and_gnss_takes_them_back(flight):
    """The blacked-out camera's UAV flies on its gyro and constant velocity for 3 s: it drifts most."""
    for vid in (1, 2):
        errors = _errors(flight, vid)
        jammed = [e for t, e in errors.items() if 8.0 <= t <= 22.0]
        after = [e for t, e in errors.items() if t >= 26.0]
        assert max(jammed) < 5.0, max(jammed)
        assert max(after) < 2.0, max(after)


def test_each_uav_reports_its_map_in_3d_with_its_landmarks_below_it(flight):
    """The map each UAV sends with its status is 3-D (bus.landmark_map): heights from the launch point
    and full covariances, the points the camera sees on the ground below the UAV (it flies 15 m over
    the relief), each covariance positive definite."""
    for vid in (1, 2):
        record = json.loads((flight / f"map_v{vid}.json").read_text())
        heights, cov_z = np.array(record["z_m"]), np.array(record["cov_z_m2"])
        assert record["landmarks"] == len(heights) == len(cov_z) > 5
        assert np.all(heights < 0.0), heights  # the ground under a UAV that climbs and descends with it
        assert np.all(cov_z[:, 2] > 0.0)
