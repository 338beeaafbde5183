"""A scenario with a GNSS jammer, run as real processes: the vehicle inside flags GNSS unhealthy
within seconds (ESTIMATOR_STATUS glitch flag, seen by the ground station), recovers after, and
every fault change is an event counted in the summary."""

import json

import pytest

from tests.integration.conftest import read_summary, run_swarm

pytestmark = pytest.mark.integration

SCENARIO = """
name = "jam"
[world]
vehicles = 3
seed = 4
[clock]
duration_s = 36
[[faults]]
kind = "jam-gnss"
center_m = [0.0, 0.0]
radius_m = 40.0
start_s = 10.0
for_s = 15.0
"""


def test_jammed_vehicle_flags_gnss_and_recovers(tmp_path):
    scenario = tmp_path / "jam.toml"
    scenario.write_text(SCENARIO)
    result = run_swarm(tmp_path, str(scenario), report=True)
    assert result.returncode == 0, result.stdout + result.stderr
    run_dir = tmp_path / "jam"
    events = [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()]
    health = [(e["event"], e["vehicle"], e["t_s"]) for e in events if e["event"].startswith("gnss_")]
    assert [h[:2] for h in health] == [("gnss_unhealthy", 1), ("gnss_healthy", 1)], health
    assert 10.0 < health[0][2] <= 12.0 and 25.0 < health[1][2] <= 31.0
    summary = read_summary(run_dir)
    assert {k: summary["events"].get(k) for k in ("fault_added", "fault_started", "fault_expired")} == {
        "fault_added": 1,
        "fault_started": 1,
        "fault_expired": 1,
    }
    assert summary["vehicles"]["1"]["rmse_m"] < 2.0
    assert "jam-gnss" in (run_dir / "report.html").read_text()


@pytest.mark.parametrize(
    "text, message",
    [
        ("name = [", "not valid TOML"),
        ('[[faults]]\nkind = "teleport"', "faults.0"),
        (
            '[world]\nvehicles = 2\n[[faults]]\nkind = "blackout"\nvehicle = 7\nsensor = "gnss"',
            "vehicle 7 does not exist",
        ),
        ('[[faults]]\nkind = "jam-gnss"\ncenter_m = [0, 0]\nradius_m = -5', "radius_m"),
    ],
)
def test_bad_scenarios_get_a_one_line_error(tmp_path, text, message):
    scenario = tmp_path / "bad.toml"
    scenario.write_text(text)
    result = run_swarm(tmp_path, str(scenario), timeout_s=60)
    assert result.returncode == 1
    assert message in result.stderr and len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert not any(tmp_path.glob("*/config.json"))
