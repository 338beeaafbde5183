"""Link faults applied by the receiving processes' bus layers, measured end to end over real
processes: each fault's observed effect is within tolerance of what was asked, and the swarm keeps
running (every vehicle is scored to the end).

MAVLink streams are signed, and MAVLink 2 signing has no replay window: a frame that arrives after
a newer one of its stream is rejected as a replay. Reordering on a signed link therefore costs the
overtaken frames, exactly as pymavlink or an autopilot would treat them."""

import json

import pytest

from tests.integration.conftest import read_summary, run_swarm

pytestmark = pytest.mark.integration
DURATION_S = 20
SCENARIO = f"""
name = "links"
[world]
vehicles = 3
seed = 6
[clock]
duration_s = {DURATION_S}
tick_s = 0.02   # the ground station measures latency in clock ticks: a fine clock measures it finely
[vehicle]
mavlink_rate_hz = 50   # every cycle's estimate: the link statistics count frames, more frames measure them finer

[[faults]]   # vehicle 2 loses 30% of its IMU samples
kind = "loss"
dst = "v2"
topic = "imu"
percent = 30

[[faults]]   # vehicle 3 receives 20% of its odometry twice
kind = "duplicate"
dst = "v3"
topic = "odom"
percent = 20

[[faults]]   # vehicle 1's GNSS fixes arrive 300 ms late
kind = "delay"
dst = "v1"
topic = "gnss"
delay_s = 0.3

[[faults]]   # the ground station hears vehicle 1 200 +- 50 ms late
kind = "delay"
src = "v1"
dst = "gs"
topic = "mavlink"
delay_s = 0.2
jitter_s = 0.05

[[faults]]   # ... loses vehicle 2's MAVLink in Gilbert-Elliott bursts, 20% overall
kind = "loss"
src = "v2"
dst = "gs"
topic = "mavlink"
percent = 20
burst = 4

[[faults]]   # ... and holds back 25% of vehicle 3's frames by 60 ms
kind = "reorder"
src = "v3"
dst = "gs"
topic = "mavlink"
percent = 25
gap_s = 0.06
"""


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The scenario twice, with the same seed."""
    dirs = []
    for _ in range(2):
        out = tmp_path_factory.mktemp("links")
        scenario = out / "links.toml"
        scenario.write_text(SCENARIO)
        result = run_swarm(out, str(scenario))
        assert result.returncode == 0, result.stdout + result.stderr
        dirs.append(out / "links")
    return dirs


@pytest.fixture(scope="module")
def run(runs):
    return runs[0]


def test_runs_with_link_faults_are_reproducible(runs):
    a, b = runs
    assert (a / "summary.json").read_text() == (b / "summary.json").read_text()
    assert (a / "metrics.csv").read_bytes() == (b / "metrics.csv").read_bytes()


def test_the_swarm_keeps_running_and_every_vehicle_is_scored(run):
    summary = read_summary(run)
    estimates = DURATION_S * 50 + 1
    assert summary["status"] == "complete" and summary["faults"]["total"] == 6
    assert summary["vehicles"]["2"]["samples"] > 0.6 * estimates
    for vid in ("1", "3"):  # reordered by jitter or held back: overtaken frames are rejected as replays
        vehicle = summary["vehicles"][vid]
        assert 0.5 * estimates < vehicle["samples"] < estimates <= vehicle["samples"] + vehicle["mavlink_rejected"]
    assert set(summary["rejected"]["by_process"]["groundstation"]) == {"replay"}
    assert summary["swarm"]["rmse_m"] < 1.0


def test_sensor_loss_duplication_and_delay_at_the_vehicles(run):
    vehicles = read_summary(run)["vehicles"]
    imu_samples = DURATION_S * 100 + 1
    assert vehicles["2"]["sensor_samples_lost"] / imu_samples == pytest.approx(0.30, abs=0.04)
    assert vehicles["3"]["sensor_duplicates"] / (DURATION_S * 50 + 1) == pytest.approx(0.20, abs=0.04)
    fixes = DURATION_S * 5 + 1
    assert vehicles["1"]["late_fused"] >= fixes - 2 and vehicles["1"]["dropped_stale"] == 0


def test_mavlink_delay_loss_and_reordering_at_the_ground_station(run):
    summary = read_summary(run)
    timing = json.loads((run / "timing.json").read_text())
    latency = timing["vehicles"]["1"]["mavlink_latency_mean_s"]
    assert latency == pytest.approx(0.2 + 0.01, abs=0.03)  # + half a 20 ms clock tick on average
    assert timing["vehicles"]["2"]["mavlink_latency_mean_s"] < 0.05
    link2, link3 = summary["vehicles"]["2"]["mavlink_link"], summary["vehicles"]["3"]["mavlink_link"]
    assert link2["loss_rate"] == pytest.approx(0.20, abs=0.06)
    assert link3["reordered"] / link3["received"] == pytest.approx(0.25, abs=0.05)
    assert link3["lost"] == 0 and summary["vehicles"]["1"]["mavlink_link"]["lost"] <= 5  # jitter reorders a few
