"""Vehicles started together with `--id auto` (as compose replicas are), holding only the enroll
login, claim distinct ids from the ground station, receive their own login and signing key, and
the swarm runs with them (every estimate accepted under its own key)."""

import json
import os
import subprocess
import sys

import pytest

from bus.config import build_config
from bus.secrets import role_env, write_secrets
from launch.child import Child, free_port, wait_for_port
from tests.integration.conftest import ESTIMATES_PER_S, read_summary

pytestmark = pytest.mark.integration


def test_vehicles_starting_together_claim_distinct_ids(tmp_path):
    secrets, port = write_secrets(tmp_path / "secrets", vehicles=3), free_port()
    config = build_config({"world": {"vehicles": 3, "seed": 2}, "clock": {"duration_s": 6}})
    config.dump(tmp_path / "config.json")
    config.for_vehicle().dump(tmp_path / "vehicle.json")
    cli, conf, run_dir = [sys.executable, "-m", "cli"], str(tmp_path / "config.json"), tmp_path / "run"
    processes = []

    def start(name: str, args: list[str], role: str, **extra: str) -> subprocess.Popen:
        env = {**os.environ, **role_env(secrets, role), "SWARMLOC_ZENOH_CONNECT": f"tcp/127.0.0.1:{port}", **extra}
        process = subprocess.Popen(
            cli + args, env=env, stdout=subprocess.DEVNULL, stderr=open(tmp_path / f"{name}.log", "wb")
        )
        processes.append(process)
        return process

    router = start(
        "router",
        ["router", "--listen", f"tcp/127.0.0.1:{port}", "--credentials", str(secrets / "credentials.txt")],
        "router",
    )
    wait_for_port(port, 15.0, Child("router", router, tmp_path / "router.log", True))
    for name in ("alpha", "bravo", "charlie"):  # before the ground station: they retry until it answers
        start(
            name,
            ["vehicle", "--config", str(tmp_path / "vehicle.json"), "--id", "auto"],
            "enroll",
            SWARMLOC_VEHICLE_NAME=name,
        )
    gs = start("gs", ["gs", "--config", conf, "--run-dir", str(run_dir), "--quiet"], "groundstation")
    start("world", ["sim", "--config", conf], "world")
    try:
        assert gs.wait(timeout=120) == 0, (tmp_path / "gs.log").read_text()[-2000:]
    finally:
        for process in processes:
            if process.poll() is None:
                process.terminate()
            process.wait(timeout=10)
    claims = json.loads((run_dir / "claims.json").read_text())
    assert sorted(claims["ids"].values()) == [1, 2, 3] and set(claims["ids"]) == {"alpha", "bravo", "charlie"}
    summary = read_summary(run_dir)
    samples = {vid: v["samples"] for vid, v in summary["vehicles"].items()}
    assert samples == dict.fromkeys(("1", "2", "3"), 6 * ESTIMATES_PER_S + 1)
    assert all(v["mavlink_rejected"] == 0 for v in summary["vehicles"].values())  # each signed with its own key
