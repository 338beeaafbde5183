"""Processes that die and come back: a vehicle killed by the fault plan is restarted by `swarm up`,
re-initialises from GNSS and rejoins with reset_counter counted up, at the plan's sim times;
`--restart on-failure` brings back a vehicle and the ground station after an outside SIGKILL, and
the ground station appends to the same run directory, losing at most about a second of metrics."""

import csv
import json
import os
import signal
import subprocess

import pytest

from tests.integration.conftest import (
    ESTIMATES_PER_S,
    processes_matching,
    read_summary,
    run_swarm,
    swarm_command,
    wait_for_metrics,
)

pytestmark = pytest.mark.integration
KILL = """
name = "kill"
[world]
vehicles = 3
seed = 8
[clock]
duration_s = 40
[[faults]]
kind = "kill"
vehicle = 2
start_s = 10.0
restart_after_s = 4.0
"""


def _rows(run, vehicle: int) -> list[dict]:
    with (run / "metrics.csv").open() as handle:
        return [r for r in csv.DictReader(handle) if r["vehicle"] == str(vehicle)]


def test_killed_vehicle_is_restarted_and_rejoins_with_reset_counter(tmp_path):
    (tmp_path / "kill.toml").write_text(KILL)
    result = run_swarm(tmp_path, str(tmp_path / "kill.toml"))
    assert result.returncode == 0, result.stdout + result.stderr
    run = tmp_path / "kill"
    assert "vehicle-2 killed by fault" in result.stdout and "vehicle-2 restarted" in result.stdout
    summary = read_summary(run)
    assert summary["status"] == "complete" and summary["vehicles"]["2"]["reset_counter"] >= 1
    rows = _rows(run, 2)
    before = [r for r in rows if float(r["t_s"]) < 10.5]
    after = [r for r in rows if float(r["t_s"]) > 14.0]
    assert before and all(r["reset_counter"] == "0" for r in before)
    assert after and float(after[-1]["t_s"]) == 40.0 and all(int(r["reset_counter"]) >= 1 for r in after)
    assert max(float(r["err_pos_m"]) for r in after[len(after) // 2 :]) < 2.0  # re-initialised from GNSS
    events = [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines()]
    lives = [e for e in events if e.get("vehicle") == 2 and e["event"] in ("vehicle_joined", "vehicle_lost")]
    assert [e["event"] for e in lives][:3] == ["vehicle_joined", "vehicle_lost", "vehicle_joined"]
    # lockstep holds the clock for the supervisor: the kill and the rejoin happen at the plan's times
    assert 10.0 <= lives[1]["t_s"] <= 10.2 and 14.0 <= lives[2]["t_s"] <= 14.2


def test_restart_on_failure_brings_back_a_vehicle_and_the_ground_station(tmp_path):
    process = subprocess.Popen(
        swarm_command(tmp_path, "--vehicles", "3", "--duration", "40", "--name", "phoenix", "--restart", "on-failure"),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    run = tmp_path / "phoenix"
    wait_for_metrics(run, 30_000)
    os.kill(processes_matching(f"{run}/vehicle.json --id 3")[0], signal.SIGKILL)
    wait_for_metrics(run, 60_000)
    gs = processes_matching(f"gs --config {run}/config.json")
    os.kill(gs[0], signal.SIGKILL)
    output, _ = process.communicate(timeout=240)
    assert process.returncode == 0, output
    assert "vehicle-3 died" in output and "groundstation died" in output and output.count("restarted (--restart") == 2
    summary = read_summary(run)
    assert summary["status"] == "complete"
    assert summary["events"].get("groundstation_restarted") == 1
    assert summary["vehicles"]["3"]["reset_counter"] >= 1
    tick_s = json.loads((run / "config.json").read_text())["clock"]["tick_s"]
    assert tick_s == 0.5  # --restart on-failure keeps lockstep's short tick: a restarted ground station loses less
    for vid in (1, 2):  # lockstep waited for the new ground station: only what the old one had not
        # acknowledged was lost (the tick it was on and at most two the world had sent meanwhile)
        stamps = [float(r["t_s"]) for r in _rows(run, vid)]
        assert stamps[-1] == 40.0
        # (stamps are decimal text: 13.9 - 12.3 is 1.6000000000000014 in floats)
        assert max(b - a for a, b in zip(stamps, stamps[1:])) <= 3 * tick_s + 1 / ESTIMATES_PER_S + 1e-9
        assert summary["vehicles"][str(vid)]["samples"] == len(stamps)
        assert summary["vehicles"][str(vid)]["consistency"]["samples"] == len(stamps)  # the whole run's too
