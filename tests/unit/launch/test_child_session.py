"""Where `swarm up`'s children run (launch.children): each in a process group of its own, all in the
session `swarm up` runs in, so that the lockstep world's lower priority orders it behind the swarm's
own vehicles and never behind the machine's other sessions (docs/decisions/scale.md)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

# The forked child's path (launch.children._child) up to the command, the command replaced by a
# report of where it runs: its session, its process group, its pid and its parent's session.
CHILD = """
import json, os, runpy, sys
from launch import children
parent_session = os.getsid(0)
def report(*args, **kwargs):
    print(json.dumps([os.getsid(0), os.getpgid(0), os.getpid(), parent_session]))
runpy.run_module = report
children._child(["vehicle", "--id", "1"], dict(os.environ), sys.argv[1], True)
"""


LINUX = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="sessions and process groups as Linux keeps them"
)


@LINUX
def test_a_forked_child_leads_its_own_group_in_the_session_swarm_up_runs_in(tmp_path):
    done = subprocess.run([sys.executable, "-c", CHILD, str(tmp_path / "child.log")], capture_output=True, text=True,
                          timeout=60)  # fmt: skip
    session, group, pid, parent_session = json.loads(done.stdout)
    assert (session, group) == (parent_session, pid)


@LINUX
def test_a_plain_subprocess_child_does_the_same(tmp_path):
    """``SWARMLOC_FORKSERVER=0``: `python -m cli ...` started by subprocess."""
    script = (
        "import os, pathlib, sys; from launch import children; "
        "p = children.start(['--help'], dict(os.environ), pathlib.Path(sys.argv[1]), inherit_stdout=False); "
        "print(os.getsid(0), os.getsid(p.pid), os.getpgid(p.pid), p.pid, flush=True); p.wait()"
    )
    env = {**os.environ, "SWARMLOC_FORKSERVER": "0"}
    done = subprocess.run([sys.executable, "-c", script, str(tmp_path / "child.log")], capture_output=True, text=True,
                          env=env, timeout=60)  # fmt: skip
    own_session, child_session, child_group, child_pid = map(int, done.stdout.split())
    assert (child_session, child_group) == (own_session, child_pid)
