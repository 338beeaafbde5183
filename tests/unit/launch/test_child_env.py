"""What `swarm up` puts in its children's environment (launch.launcher.Swarm.spawn)."""

from __future__ import annotations

import pytest

from bus.config import SwarmConfig
from launch import launcher


@pytest.fixture
def started(monkeypatch, tmp_path):
    """The environments `Swarm.spawn` starts children with, by child name (nothing is started)."""
    envs: dict[str, dict[str, str]] = {}

    def start(args, env, log_path, *, inherit_stdout=False):
        envs[args[0]] = env
        return object()

    monkeypatch.setattr(launcher.children, "start", start)
    swarm = launcher.Swarm(SwarmConfig(), tmp_path, False)
    return swarm, envs


def test_in_lockstep_every_child_but_the_router_runs_zenoh_on_one_thread(started, monkeypatch):
    monkeypatch.delenv("ZENOH_RUNTIME", raising=False)
    swarm, envs = started
    for name in ("router", "sim", "gs", "vehicle"):
        swarm.spawn(name if name != "vehicle" else "vehicle-1", [name], essential=False)
    assert "ZENOH_RUNTIME" not in envs["router"]  # it serves every link
    assert {envs[name]["ZENOH_RUNTIME"] for name in ("sim", "gs", "vehicle")} == {launcher.ONE_ZENOH_RUNTIME}


def test_realtime_children_keep_zenohs_default_runtime(monkeypatch, tmp_path):
    monkeypatch.delenv("ZENOH_RUNTIME", raising=False)
    envs = {}
    monkeypatch.setattr(launcher.children, "start", lambda args, env, *_, **__: envs.setdefault(args[0], env))
    swarm = launcher.Swarm(SwarmConfig.model_validate({"clock": {"mode": "realtime"}}), tmp_path, False)
    swarm.spawn("vehicle-1", ["vehicle"], essential=False)
    assert "ZENOH_RUNTIME" not in envs["vehicle"]


def test_a_users_own_zenoh_runtime_wins(started, monkeypatch):
    monkeypatch.setenv("ZENOH_RUNTIME", "(app: (worker_threads: 2))")
    swarm, envs = started
    swarm.spawn("vehicle-1", ["vehicle"], essential=False)
    swarm.spawn("router", ["router"], essential=True)
    assert envs["vehicle"]["ZENOH_RUNTIME"] == envs["router"]["ZENOH_RUNTIME"] == "(app: (worker_threads: 2))"
