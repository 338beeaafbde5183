"""Helpers for integration tests: run `swarm up` as a real subprocess with a loopback zenoh router."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bus.config import VehicleConfig

ESTIMATES_PER_S = round(VehicleConfig().mavlink_rate_hz)  # ODOMETRY frames a vehicle sends the ground station


def swarm_command(out: Path, *args: str, report: bool = False) -> list[str]:
    """`swarm up` with ``args``; with ``report`` it writes its report (as by default), else --no-report:
    only the tests about reports pay for the figures."""
    return [
        sys.executable,
        "-m",
        "cli",
        "up",
        "--quiet",
        "--out",
        str(out),
        *(() if report else ("--no-report",)),
        *args,
    ]


def run_swarm(out: Path, *args: str, timeout_s: float = 240, report: bool = False) -> subprocess.CompletedProcess:
    return subprocess.run(
        swarm_command(out, *args, report=report),
        capture_output=True,
        text=True,
        timeout=timeout_s,
        env={**os.environ, "COLUMNS": "200"},
    )


def wait_for_metrics(run_dir: Path, min_bytes: int, timeout_s: float = 120) -> None:
    """Wait until the run's metrics.csv has grown past ``min_bytes`` (scoring is under way)."""
    metrics, deadline = run_dir / "metrics.csv", time.monotonic() + timeout_s
    while not (metrics.exists() and metrics.stat().st_size > min_bytes):
        assert time.monotonic() < deadline, f"the run in {run_dir} never got that far"
        time.sleep(0.2)


def read_summary(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text())


def processes_matching(text: str) -> list[int]:
    """PIDs whose command line contains ``text`` (Linux /proc)."""
    pids = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
            except OSError:
                continue
            if text in cmdline:
                pids.append(int(entry.name))
    return pids


@pytest.fixture(scope="session")
def three_vehicle_runs(tmp_path_factory) -> list[Path]:
    """Two lockstep runs of 3 vehicles for 30 s with the same seed (shared by several tests); the first
    writes its report, the second does not (--no-report)."""
    dirs = []
    for copy in range(2):
        out = tmp_path_factory.mktemp("runs")
        result = run_swarm(
            out, "--vehicles", "3", "--duration", "30", "--seed", "11", "--name", "same", report=copy == 0
        )
        assert result.returncode == 0, result.stdout + result.stderr
        dirs.append(out / "same")
    return dirs
