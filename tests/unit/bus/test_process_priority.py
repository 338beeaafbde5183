"""A lower CPU priority for the processes off a lockstep run's critical path (bus.process.
lower_cpu_priority, applied by cli.process_commands to the world and the ground station): the calling
thread's nice value, and the session's autogroup when the process leads its session."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from bus.config import build_config
from bus.process import lower_cpu_priority
from cli.process_commands import background_niceness


@pytest.fixture
def priority(monkeypatch):
    """os.getpriority / setpriority on a fake thread that starts at nice ``state['nice']``."""
    state = {"nice": 0, "calls": []}

    def set_priority(which, who, value):
        state["calls"].append((which, who, value))
        state["nice"] = value

    monkeypatch.setattr(os, "getpriority", lambda which, who: state["nice"])
    monkeypatch.setattr(os, "setpriority", set_priority)
    return state


def test_niceness_zero_asks_for_nothing(priority, tmp_path):
    group = tmp_path / "autogroup"
    assert lower_cpu_priority(0, group) == 0
    assert priority["calls"] == [] and not group.exists()


def test_a_session_leader_sets_its_thread_and_its_sessions_autogroup(priority, tmp_path, monkeypatch):
    monkeypatch.setattr(os, "getsid", lambda pid: os.getpid())
    group = tmp_path / "autogroup"
    assert lower_cpu_priority(19, group) == 19
    assert priority["calls"] == [(os.PRIO_PROCESS, 0, 19)]  # who 0: the calling thread, inherited by later ones
    assert group.read_text() == "19\n"


def test_a_process_sharing_its_shells_session_leaves_the_session_alone(priority, tmp_path, monkeypatch):
    monkeypatch.setattr(os, "getsid", lambda pid: os.getpid() + 1)
    group = tmp_path / "autogroup"
    assert lower_cpu_priority(10, group) == 10
    assert priority["nice"] == 10 and not group.exists()


def test_a_thread_already_nicer_keeps_its_niceness(priority, tmp_path, monkeypatch):
    monkeypatch.setattr(os, "getsid", lambda pid: os.getpid() + 1)
    priority["nice"] = 15
    assert lower_cpu_priority(5, tmp_path / "autogroup") == 5
    assert priority["nice"] == 15


def test_a_refused_change_applies_nothing(tmp_path, monkeypatch):
    def refuse(*_):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "getpriority", lambda *_: 0)
    monkeypatch.setattr(os, "setpriority", refuse)
    monkeypatch.setattr(os, "getsid", lambda pid: os.getpid())
    group = tmp_path / "autogroup"
    assert lower_cpu_priority(19, group) == 0
    assert not group.exists()


def test_a_kernel_without_autogroups_still_gets_the_threads_niceness(priority, tmp_path, monkeypatch):
    monkeypatch.setattr(os, "getsid", lambda pid: os.getpid())
    assert lower_cpu_priority(19, tmp_path / "no such dir" / "autogroup") == 19
    assert priority["nice"] == 19


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="nice values and autogroups are Linux's")
def test_a_real_session_leader_runs_at_the_niceness_it_asked_for():
    """In a child of its own session, as `swarm up` starts its processes: the kernel reports the
    niceness for the thread, for a thread started afterwards, and (where the kernel has autogroups
    and this user may write the group's file) for the session's group."""
    script = (
        "import json, os, threading; from bus.process import lower_cpu_priority, AUTOGROUP; "
        "applied = lower_cpu_priority(7); seen = []; "
        "t = threading.Thread(target=lambda: seen.append(os.getpriority(os.PRIO_PROCESS, 0))); t.start(); t.join(); "
        "group = AUTOGROUP.read_text() if os.access(AUTOGROUP, os.W_OK) else ''; "
        "print(json.dumps([applied, os.getpriority(os.PRIO_PROCESS, 0), seen[0], group]))"
    )
    done = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, start_new_session=True, check=True, timeout=60
    )
    applied, main_nice, thread_nice, group = json.loads(done.stdout)
    assert (applied, main_nice, thread_nice) == (7, 7, 7)
    if group:
        assert group.split()[-1] == "7"  # "/autogroup-N nice 7"


@pytest.mark.parametrize(
    ("role", "mode", "expected"),
    [
        ("world", "lockstep", 19),
        ("groundstation", "lockstep", 19),
        ("vehicle", "lockstep", 0),
        ("world", "realtime", 0),
    ],
)
def test_the_world_and_the_ground_station_yield_to_the_vehicles_in_lockstep_only(role, mode, expected):
    config = build_config({"clock": {"mode": mode}})
    assert background_niceness(role, config) == expected


def test_a_niceness_of_zero_keeps_the_default_priority():
    config = build_config({"clock": {"mode": "lockstep", "background_niceness": 0}})
    assert background_niceness("world", config) == 0
