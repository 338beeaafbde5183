"""`swarm fault ...` against a running swarm: faults are added, listed with their state, removed and
logged; a killed vehicle comes back with reset_counter counted up; bad input gets a one-line error
and leaves the plan unchanged; with no swarm running the command says so."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from tests.integration.conftest import read_summary, swarm_command

pytestmark = pytest.mark.integration


def fault(out, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cli", "fault", *args, "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "COLUMNS": "200"},
    )


def _events(run) -> list[dict]:
    return [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines() if line.endswith("}")]


def _wait_for(condition, what: str, timeout_s: float = 90) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        assert time.monotonic() < deadline, f"timed out waiting for {what}"
        time.sleep(0.2)


def test_fault_commands_against_a_running_swarm(tmp_path):
    assert "no swarm running" in fault(tmp_path, "list").stderr
    process = subprocess.Popen(
        swarm_command(tmp_path, "--vehicles", "3", "--duration", "3000", "--name", "live"),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    run = tmp_path / "live"
    try:
        _wait_for(
            lambda: (
                (run / "swarm.json").exists()
                and (run / "metrics.csv").exists()
                and (run / "metrics.csv").stat().st_size > 5_000
            ),
            "the run to start",
        )
        added = fault(tmp_path, "add", "loss", "--to", "v3", "--topic", "imu", "--percent", "30", "--name", "imu-loss")
        assert added.returncode == 0 and "plan version 1" in added.stdout, added.stderr
        assert (
            fault(tmp_path, "add", "jam-gnss", "--center", "0,-20", "--radius", "25m", "--for", "60s").returncode == 0
        )
        before = fault(tmp_path, "list").stdout
        assert "imu-loss" in before and "jam-gnss-1" in before and "active" in before
        for args, message in [
            (["add", "loss", "--to", "v9", "--percent", "10"], "matches nothing"),
            (["add", "delay", "--delay", "-200ms"], "--delay"),
            (["add", "loss", "--percent", "130"], "--percent"),
            (["add", "teleport"], "unknown fault kind"),
            (["remove", "ghost"], "no fault named 'ghost'"),
            (["kill", "v7"], "vehicle 7 does not exist"),
            (["add", "lie", "--vehicle", "v3"], "would tell the truth"),
            (["add", "lie", "--vehicle", "v9", "--offset", "30,0"], "vehicle 9 does not exist"),
            (["add", "lie", "--vehicle", "v2", "--offset", "30"], "--offset"),
            (["add", "lie", "--vehicle", "v2", "--cov-scale", "0"], "--cov-scale"),
            (["add", "lie", "--vehicle", "v2", "--stale", "-5s"], "--stale"),
            (["add", "accuse", "--vehicle", "v2", "--names", "v1,v2"], "would accuse itself"),
            (["add", "accuse", "--vehicle", "v2", "--names", "v1,v9"], "--names v9 does not exist"),
            (["add", "accuse", "--vehicle", "v2", "--names", "one"], "--names"),
            (["add", "accuse", "--vehicle", "v2"], "--names"),
        ]:
            result = fault(tmp_path, *args)
            assert result.returncode == 1 and message in result.stderr, (args, result.stderr)
            assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
        assert "plan v2" in fault(tmp_path, "list").stdout  # unchanged by the bad requests
        assert fault(tmp_path, "add", "accuse", "--vehicle", "v3", "--names", "v1,v2").returncode == 0
        assert fault(tmp_path, "kill", "v2", "--restart-after", "3s").returncode == 0
        _wait_for(
            lambda: sum(e["event"] == "vehicle_joined" and e["vehicle"] == 2 for e in _events(run)) == 2,
            "vehicle 2 to come back",
        )
        assert fault(tmp_path, "remove", "imu-loss").returncode == 0
        assert fault(tmp_path, "clear").returncode == 0
        _wait_for(lambda: _scored_until(run, vehicle=2) > _kill_time(run) + 8, "vehicle 2 to publish again")
    finally:
        process.send_signal(signal.SIGINT)
        output, _ = process.communicate(timeout=60)
    summary = read_summary(run)
    assert summary["status"] == "interrupted", output
    assert summary["vehicles"]["2"]["reset_counter"] >= 1
    assert summary["vehicles"]["3"]["sensor_samples_lost"] > 0
    kinds = [e["event"] for e in _events(run)]
    assert kinds.count("fault_added") == 4 and kinds.count("fault_removed") == 4  # imu-loss, then clear: 3 more
    assert "vehicle_lost" in kinds
    resets = [
        line.split(",")[10] for line in (run / "metrics.csv").read_text().splitlines()[1:] if line.split(",")[1] == "2"
    ]
    assert resets[0] == "0" and int(resets[-1]) >= 1
    assert "vehicle-2 killed by fault kill-1" in output and "vehicle-2 restarted" in output


def _scored_until(run, *, vehicle: int) -> float:
    header, *lines = (run / "metrics.csv").read_text().splitlines()
    rows = [line.split(",") for line in lines if line.count(",") == header.count(",")]
    return max((float(r[0]) for r in rows if r[1] == str(vehicle)), default=0.0)


def _kill_time(run) -> float:
    kills = [e["t_s"] for e in _events(run) if e["event"] == "fault_started" and e.get("fault") == "kill"]
    return kills[0] if kills else float("inf")
