"""One swarm placed by an orchestrator: deploy/stack.yml on a Docker Swarm (`docker stack deploy`) of
this one node, 3 vehicles claiming their ids, the hub and per-host routers, secrets and configs as
Docker objects. The run completes, scores every vehicle, and is byte for byte the run the same seed
gives under `swarm up` on one host. Skips with the reason when no Docker engine answers; a node that
is in no swarm is made one for the test and left again after (`make test-docker`)."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.docker
ROOT = Path(__file__).resolve().parents[2]
STACK = f"swarmloc-test-{os.getpid()}"


def _docker(*args: str, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run(["docker", *args], capture_output=True, text=True, **kwargs)


@pytest.fixture
def docker_swarm():
    info = subprocess.run(["docker", "info", "--format", "{{.Swarm.LocalNodeState}}"], capture_output=True, text=True)
    if info.returncode != 0:
        pytest.skip(f"no Docker engine answers ({(info.stderr.strip().splitlines() or ['docker info failed'])[-1]})")
    joined = info.stdout.strip() == "active"
    if not joined:
        init = _docker("swarm", "init", "--advertise-addr", "127.0.0.1")
        if init.returncode != 0:
            pytest.skip(f"this Docker engine cannot be a swarm: {init.stderr.strip()[-300:]}")
    yield
    _docker("stack", "rm", STACK)
    if not joined:
        _docker("swarm", "leave", "--force")


@pytest.mark.timeout(2400)  # a first build of the image takes minutes
def test_a_stack_deployed_by_docker_swarm_flies_the_run_one_host_flies(docker_swarm, tmp_path):
    build = _docker("build", "--network", "host", "-t", "swarmloc:latest", str(ROOT), timeout=1800,
                    env={**os.environ, "DOCKER_BUILDKIT": "0"})  # fmt: skip
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    secrets, runs = tmp_path / "secrets", tmp_path / "runs"
    made = subprocess.run([sys.executable, "-m", "cli", "secrets", "--out", str(secrets), "--vehicles", "3"],
                          capture_output=True, text=True)  # fmt: skip
    assert made.returncode == 0, made.stderr
    runs.mkdir()
    os.chown(runs, 1000, 1000)  # the image's unprivileged user writes the run directory
    env = {**os.environ, "VEHICLES": "3", "SWARMLOC_SECRETS": str(secrets), "SWARMLOC_RUNS": str(runs)}
    deploy = _docker("stack", "deploy", "-c", str(ROOT / "deploy" / "stack.yml"), STACK, env=env, timeout=300)
    assert deploy.returncode == 0, deploy.stdout + deploy.stderr
    while not _ground_station_state().startswith(("Complete", "Failed")):  # the suite's timeout guards the wait
        time.sleep(1.0)
    assert _ground_station_state().startswith("Complete"), _docker("service", "logs", f"{STACK}_groundstation").stdout
    summary = json.loads((runs / "stack" / "summary.json").read_text())
    assert summary["status"] == "complete" and sorted(summary["vehicles"]) == ["1", "2", "3"]

    one_host = subprocess.run(
        [sys.executable, "-m", "cli", "up", "--vehicles", "3", "--seed", "1", "--duration", "60", "--mode",
         "lockstep", "--out", str(tmp_path), "--name", "one-host", "--quiet", "--no-report", "--no-record"],
        capture_output=True, text=True,
    )  # fmt: skip
    assert one_host.returncode == 0, one_host.stderr[-2000:]
    assert (tmp_path / "one-host" / "metrics.csv").read_bytes() == (runs / "stack" / "metrics.csv").read_bytes()


def _ground_station_state() -> str:
    """The ground station task's state (``Running 3 seconds ago``, ``Complete ...``), empty before it has one."""
    ps = _docker("service", "ps", f"{STACK}_groundstation", "--format", "{{.CurrentState}}")
    return ps.stdout.strip().splitlines()[0] if ps.stdout.strip() else ""
