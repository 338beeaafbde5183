"""Chaos run: 6 vehicles, 120 s of lockstep, a seeded random fault timeline with every kind of fault
(link delay, loss, duplication, reordering; GNSS jamming and spoofing; comm jamming; a sensor
blackout; a vehicle kill and restart). No process dies unexpectedly, the run directory is complete,
and summary.json counts every fault."""

import json

import pytest

from bus.faults import BY_KIND
from tests.integration.conftest import ESTIMATES_PER_S, read_summary, run_swarm

pytestmark = pytest.mark.integration


def test_chaos_run_survives_every_kind_of_fault(tmp_path):
    result = run_swarm(
        tmp_path, "--vehicles", "6", "--duration", "120", "--chaos", "7", "--name", "chaos", timeout_s=600, report=True
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert "died" not in result.stdout  # the planned kill is reported as a kill, nothing else died
    run = tmp_path / "chaos"
    for name in ("config.json", "metrics.csv", "events.jsonl", "summary.json", "timing.json", "report.html"):
        assert (run / name).stat().st_size > 0, name
    summary = read_summary(run)
    planned = json.loads((run / "config.json").read_text())["faults"]
    assert summary["status"] == "complete"
    # every kind of the registry that a camera-less swarm of 6 has in its chaos timelines
    assert set(summary["faults"]["by_kind"]) == {name for name, kind in BY_KIND.items() if kind.chaos_min_vehicles <= 6}
    assert summary["faults"]["total"] == len(planned) and summary["faults"]["names"] == [f["name"] for f in planned]
    assert summary["events"]["fault_added"] == summary["events"]["fault_started"] == len(planned)
    assert summary["events"]["fault_expired"] == len(planned)  # every chaos fault ends inside the run
    for vid in map(str, range(1, 7)):  # scored to the end (MAVLink loss and replays cost some samples)
        assert summary["vehicles"][vid]["samples"] > 0.6 * 120 * ESTIMATES_PER_S, vid
        track = (run / "tum" / f"est_v{vid}.tum").read_text().splitlines()
        assert len(track) == summary["vehicles"][vid]["samples"] and float(track[-1].split()[0]) > 119.0
