"""A swarm across hosts: a router host, a ground-station host (world and ground station), and two
vehicle hosts, as network namespaces joined by veth links. Vehicle host A runs a second zenoh
router joined to the first (the two-router deployment of the README); its vehicles connect to it
locally, while vehicle host B connects to the main router. Logins, access control and signing on.
Started in the worst order, with no sleeps: everything else before the routers (they wait for
them). Every vehicle is scored, and the run is byte for byte the one the same seed gives on one host."""

import os
import subprocess
import sys

import pytest

from bus.config import build_config
from bus.secrets import role_env, write_secrets
from tests.integration.conftest import ESTIMATES_PER_S, read_summary
from tests.integration.netns import Lab, netns_unavailable

pytestmark = pytest.mark.integration
DURATION_S = 15


@pytest.fixture
def lab():
    reason = netns_unavailable()
    if reason:
        pytest.skip(f"multi-host test needs network namespaces: {reason}")
    lab = Lab(["rtr", "gs", "va", "vb"])
    yield lab
    lab.close()


def test_swarm_across_four_hosts_and_two_routers(lab, tmp_path):
    secrets = write_secrets(tmp_path / "secrets", vehicles=3)
    main = f"tcp/{lab.addresses['rtr']}:7447"
    config = build_config(
        {
            "name": "multihost",
            "world": {"vehicles": 3, "seed": 3},
            "clock": {"duration_s": DURATION_S, "start_timeout_s": 90},
        }
    )
    config.dump(tmp_path / "config.json")
    config.for_vehicle().dump(tmp_path / "vehicle.json")
    cli = [sys.executable, "-m", "cli"]
    processes = []

    def start(host: str, name: str, args: list[str], role: str, connect: str | None = None):
        env = {**os.environ, "PYTHONUNBUFFERED": "1", **role_env(secrets, role)}
        if connect:
            env["SWARMLOC_ZENOH_CONNECT"] = connect
        log = open(tmp_path / f"{name}.log", "wb")
        processes.append((name, lab.run(host, cli + args, env=env, log=log)))

    creds = ["--credentials", str(secrets / "credentials.txt")]
    conf, vconf = str(tmp_path / "config.json"), str(tmp_path / "vehicle.json")
    run_dir = tmp_path / "run"
    start("gs", "world", ["sim", "--config", conf], "world", main)
    start("va", "vehicle-1", ["vehicle", "--config", vconf, "--id", "1"], "vehicle-1", "tcp/127.0.0.1:7448")
    start("va", "vehicle-2", ["vehicle", "--config", vconf, "--id", "2"], "vehicle-2", "tcp/127.0.0.1:7448")
    start("vb", "vehicle-3", ["vehicle", "--config", vconf, "--id", "3"], "vehicle-3", main)
    start("gs", "groundstation", ["gs", "--config", conf, "--run-dir", str(run_dir), "--quiet"], "groundstation", main)
    start("va", "router-b", ["router", "--listen", "tcp/127.0.0.1:7448", "--connect", main, *creds], "router")
    start("rtr", "router-a", ["router", "--listen", "tcp/0.0.0.0:7447", *creds], "router")
    try:
        gs = dict(processes)["groundstation"]
        assert gs.wait(timeout=240) == 0, (tmp_path / "groundstation.log").read_text()[-2000:]
    finally:
        for _, process in processes:
            if process.poll() is None:
                process.terminate()
        for _, process in processes:
            try:
                process.wait(timeout=10)
            except Exception:
                process.kill()
    summary = read_summary(run_dir)
    assert summary["status"] == "complete"
    for vid in ("1", "2", "3"):
        assert summary["vehicles"][vid]["samples"] == DURATION_S * ESTIMATES_PER_S + 1, vid
        assert summary["vehicles"][vid]["rmse_m"] < 1.5 and summary["vehicles"][vid]["mavlink_rejected"] == 0

    # the same seed on one host (`swarm up`, lockstep): the same run, byte for byte
    one_host = subprocess.run(
        [*cli, "up", "--vehicles", "3", "--seed", "3", "--duration", str(DURATION_S), "--mode", "lockstep",
         "--out", str(tmp_path), "--name", "one-host", "--quiet", "--no-report", "--no-record"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert one_host.returncode == 0, one_host.stdout[-2000:] + one_host.stderr[-2000:]
    assert (tmp_path / "one-host" / "metrics.csv").read_bytes() == (run_dir / "metrics.csv").read_bytes()
    assert _scored(read_summary(tmp_path / "one-host")) == _scored(summary)


def _scored(summary: dict) -> dict:
    """What a run scored, without its name."""
    return {k: v for k, v in summary.items() if k != "name"}
