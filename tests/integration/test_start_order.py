"""Start order does not matter: vehicles, world and ground station started before any router wait
for it (saying so once) and form the swarm when it comes 10 s later; a router that never comes is a
one-line error when the wait is over."""

import os
import subprocess
import sys
import time

import pytest

from bus.config import build_config
from bus.secrets import role_env, write_secrets
from launch.child import free_port
from tests.integration.conftest import ESTIMATES_PER_S, read_summary

pytestmark = pytest.mark.integration
CLI = [sys.executable, "-m", "cli"]
LATE_S = 10.0
DURATION_S = 10


def test_processes_started_before_their_router_form_the_swarm(tmp_path):
    secrets, port = write_secrets(tmp_path / "secrets", vehicles=3), free_port()
    config = build_config(
        {"name": "late-router", "world": {"vehicles": 3, "seed": 4}, "clock": {"duration_s": DURATION_S}}
    )
    config.dump(tmp_path / "config.json")
    config.for_vehicle().dump(tmp_path / "vehicle.json")
    run_dir, processes = tmp_path / "run", {}

    def start(name: str, args: list[str], user: str) -> subprocess.Popen:
        env = {**os.environ, **role_env(secrets, user), "SWARMLOC_ZENOH_CONNECT": f"tcp/127.0.0.1:{port}"}
        processes[name] = subprocess.Popen(
            CLI + args, env=env, stdout=subprocess.DEVNULL, stderr=open(tmp_path / f"{name}.log", "wb")
        )
        return processes[name]

    conf, vconf = str(tmp_path / "config.json"), str(tmp_path / "vehicle.json")
    for vid in (1, 2, 3):
        start(f"vehicle-{vid}", ["vehicle", "--config", vconf, "--id", str(vid)], f"vehicle-{vid}")
    start("world", ["sim", "--config", conf], "world")
    gs = start("groundstation", ["gs", "--config", conf, "--run-dir", str(run_dir), "--quiet"], "groundstation")
    time.sleep(LATE_S)  # the scenario: the router comes 10 s late
    assert all(p.poll() is None for p in processes.values()), "a process gave up before its router came"
    start(
        "router",
        ["router", "--listen", f"tcp/127.0.0.1:{port}", "--credentials", str(secrets / "credentials.txt")],
        "router",
    )
    try:
        assert gs.wait(timeout=180) == 0, (tmp_path / "groundstation.log").read_text()[-3000:]
        for name in ("world", "vehicle-1", "vehicle-2", "vehicle-3"):
            assert processes[name].wait(timeout=30) == 0, (tmp_path / f"{name}.log").read_text()[-2000:]
    finally:
        for process in processes.values():
            if process.poll() is None:
                process.terminate()
                process.wait(timeout=10)
    summary = read_summary(run_dir)
    assert summary["status"] == "complete"
    samples = {vid: v["samples"] for vid, v in summary["vehicles"].items()}
    assert samples == dict.fromkeys(("1", "2", "3"), DURATION_S * ESTIMATES_PER_S + 1)
    for name in ("world", "vehicle-1", "groundstation"):  # each said once that it was waiting, and for what
        log = (tmp_path / f"{name}.log").read_text()
        assert log.count("waiting for the zenoh router at tcp/127.0.0.1") == 1, name


def test_a_router_that_never_comes_is_a_one_line_error(tmp_path):
    build_config({"world": {"vehicles": 1}}).for_vehicle().dump(tmp_path / "vehicle.json")
    env = {
        **os.environ,
        "SWARMLOC_ZENOH_CONNECT": f"tcp/127.0.0.1:{free_port()}",
        "SWARMLOC_ZENOH_CONNECT_TIMEOUT_S": "2",
    }
    result = subprocess.run(
        CLI + ["vehicle", "--config", str(tmp_path / "vehicle.json"), "--id", "1"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1
    errors = [line for line in result.stderr.splitlines() if "error" in line]
    assert errors == [line for line in errors if line.startswith("swarm: error:")] and len(errors) == 1
    assert "no zenoh router answered within 2 s" in errors[0] and "Traceback" not in result.stderr


def _manual_swarm(tmp_path, extra_clock: dict):
    """Router, ground station, world and two vehicles as separate processes; returns (start, processes)."""
    secrets, port = write_secrets(tmp_path / "secrets", vehicles=2), free_port()
    config = build_config({"world": {"vehicles": 2, "seed": 4}, "clock": {"duration_s": 600, **extra_clock}})
    config.dump(tmp_path / "config.json")
    config.for_vehicle().dump(tmp_path / "vehicle.json")
    processes = {}

    def start(name: str, args: list[str], user: str) -> subprocess.Popen:
        env = {**os.environ, **role_env(secrets, user), "SWARMLOC_ZENOH_CONNECT": f"tcp/127.0.0.1:{port}"}
        processes[name] = subprocess.Popen(
            CLI + args, env=env, stdout=subprocess.DEVNULL, stderr=open(tmp_path / f"{name}.log", "wb")
        )
        return processes[name]

    conf, vconf = str(tmp_path / "config.json"), str(tmp_path / "vehicle.json")
    start(
        "router",
        ["router", "--listen", f"tcp/127.0.0.1:{port}", "--credentials", str(secrets / "credentials.txt")],
        "router",
    )
    start("groundstation", ["gs", "--config", conf, "--run-dir", str(tmp_path / "run"), "--quiet"], "groundstation")
    start("world", ["sim", "--config", conf], "world")
    for vid in (1, 2):
        start(f"vehicle-{vid}", ["vehicle", "--config", vconf, "--id", str(vid)], f"vehicle-{vid}")
    return processes


@pytest.mark.parametrize(
    "victim, survivor, status",
    [("world", "groundstation", "world-lost"), ("groundstation", "world", "groundstation-lost")],
)
def test_the_world_and_the_ground_station_end_the_run_when_the_other_is_gone(tmp_path, victim, survivor, status):
    from tests.integration.conftest import wait_for_metrics

    processes = _manual_swarm(tmp_path, {"gone_timeout_s": 3})
    try:
        wait_for_metrics(tmp_path / "run", 5_000)
        processes[victim].kill()
        assert processes[survivor].wait(timeout=60) == 1  # not silently waiting: it ended the run, as an error
        message = (tmp_path / f"{survivor}.log").read_text().strip().splitlines()[-1]
        assert message.startswith("swarm: error:") and "run ended" in message
        if survivor == "groundstation":
            assert read_summary(tmp_path / "run")["status"] == status
    finally:
        for process in processes.values():
            if process.poll() is None:
                process.terminate()
                process.wait(timeout=10)
