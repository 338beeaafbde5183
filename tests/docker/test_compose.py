"""The compose deployment: build the image, bring up a 3-vehicle swarm (`--scale vehicle=3`), check
that every vehicle published and the ground station's summary, written to the host, has RMSE for
each; tear it down. Skips with the reason when no Docker engine answers (`make test-docker`;
../shared/tools/docker-sandbox.sh sets one up on these machines)."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.docker
ROOT = Path(__file__).resolve().parents[2]


def _compose() -> list[str] | None:
    if shutil.which("docker") and subprocess.run(["docker", "compose", "version"], capture_output=True).returncode == 0:
        return ["docker", "compose"]
    return ["docker-compose"] if shutil.which("docker-compose") else None


@pytest.fixture
def compose(tmp_path):
    command = _compose()
    if command is None:
        pytest.skip("no docker compose / docker-compose command on this machine")
    info = subprocess.run(["docker", "info"], capture_output=True, text=True)
    if info.returncode != 0:
        pytest.skip(f"no Docker engine answers ({(info.stderr.strip().splitlines() or ['docker info failed'])[-1]})")
    project = f"swarmloc-test-{os.getpid()}"
    env = {**os.environ, "VEHICLES": "3", "COMPOSE_PROJECT_NAME": project}
    shutil.rmtree(ROOT / "runs" / "compose", ignore_errors=True)
    yield [*command, "-f", str(ROOT / "docker-compose.yml")], env
    subprocess.run(
        [*command, "-f", str(ROOT / "docker-compose.yml"), "down", "-v", "--remove-orphans"],
        env=env,
        capture_output=True,
        cwd=ROOT,
        timeout=300,
    )


@pytest.mark.timeout(2400)  # a first build of the image takes minutes
def test_compose_swarm_of_three_vehicles(compose):
    command, env = compose
    build = subprocess.run([*command, "build"], env=env, cwd=ROOT, capture_output=True, text=True, timeout=1800)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    up = subprocess.run(
        [*command, "up", "-d", "--scale", "vehicle=3"], env=env, cwd=ROOT, capture_output=True, text=True, timeout=600
    )
    assert up.returncode == 0, up.stdout[-3000:] + up.stderr[-3000:]
    gs = subprocess.run(
        [*command, "ps", "-q", "groundstation"], env=env, cwd=ROOT, capture_output=True, text=True
    ).stdout.strip()
    status = subprocess.run(["docker", "wait", gs], capture_output=True, text=True, timeout=900).stdout.strip()
    logs = subprocess.run([*command, "logs", "--tail", "30"], env=env, cwd=ROOT, capture_output=True, text=True).stdout
    assert status == "0", logs[-5000:]
    summary = json.loads((ROOT / "runs" / "compose" / "summary.json").read_text())
    assert summary["status"] == "complete"
    assert set(summary["vehicles"]) == {"1", "2", "3"}
    for vid, vehicle in summary["vehicles"].items():
        assert vehicle["samples"] > 0 and vehicle["rmse_m"] < 2.0, vid
    claims = json.loads((ROOT / "runs" / "compose" / "claims.json").read_text())
    assert sorted(claims["ids"].values()) == [1, 2, 3]
