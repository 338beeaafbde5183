"""A lower CPU priority for the processes off a lockstep run's critical path (bus.process.
lower_cpu_priority, applied by cli.process_commands to the world and the ground station): the calling
thread's nice value, inside the session `swarm up` shares with its processes (launch.children)."""

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


def test_niceness_zero_asks_for_nothing(priority):
    assert lower_cpu_priority(0) == 0
    assert priority["calls"] == []


def test_the_calling_thread_gets_the_niceness(priority):
    assert lower_cpu_priority(19) == 19
    assert priority["calls"] == [(os.PRIO_PROCESS, 0, 19)]  # who 0: the calling thread, inherited by later ones


def test_a_thread_already_nicer_keeps_its_niceness(priority):
    priority["nice"] = 15
    assert lower_cpu_priority(5) == 5
    assert priority["nice"] == 15


def test_a_refused_change_applies_nothing(monkeypatch):
    def refuse(*_):
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(os, "getpriority", lambda *_: 0)
    monkeypatch.setattr(os, "setpriority", refuse)
    assert lower_cpu_priority(19) == 0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="per-thread nice values and autogroups are Linux's")
def test_a_swarm_child_runs_at_its_niceness_and_leaves_its_sessions_alone():
    """As `swarm up` starts a process (launch.children.own_process_group): the kernel reports the
    niceness for the thread and for a thread started afterwards; the child leads its own process group
    in its parent's session, and that session's autogroup keeps its nice value (a session at 19 is
    starved beside every other session of the machine)."""
    script = (
        "import json, os, pathlib, threading; from bus.process import lower_cpu_priority; "
        "from launch.children import own_process_group; "
        "group = pathlib.Path('/proc/self/autogroup'); before = group.read_text() if group.exists() else ''; "
        "own_process_group(); applied = lower_cpu_priority(7); seen = []; "
        "t = threading.Thread(target=lambda: seen.append(os.getpriority(os.PRIO_PROCESS, 0))); t.start(); t.join(); "
        "after = group.read_text() if group.exists() else ''; "
        "print(json.dumps([applied, os.getpriority(os.PRIO_PROCESS, 0), seen[0], before, after, "
        "os.getsid(0), os.getpgid(0), os.getpid()]))"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True, timeout=60)
    applied, main_nice, thread_nice, before, after, sid, pgid, pid = json.loads(done.stdout)
    assert (applied, main_nice, thread_nice) == (7, 7, 7)
    assert sid == os.getsid(0) and pgid == pid  # the parent's session, a group of its own
    assert before.split()[-1:] == after.split()[-1:]  # "/autogroup-N nice 0" untouched


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
