"""Campaigns on Dask through real processes: a scheduler and two workers started with the
stock `dask scheduler` and `dask worker` commands fly a grid of lockstep runs whose outputs equal,
byte for byte, those of the same grid flown one run at a time; a worker killed in the middle leaves
its runs to the other and nothing of them running; Ctrl-C on a local campaign leaves nothing running
and the same command resumes it; twice as many runs at once as there are cores do not hear each
other."""

import contextlib
import hashlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.integration.conftest import processes_matching

pytestmark = pytest.mark.integration
CLI = [sys.executable, "-m", "cli"]
DASK = str(Path(sys.executable).parent / "dask")


def _grid(tmp_path: Path, name: str, seeds: int, duration_s: float, vehicles: int = 2) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(
        f'name = "{name}"\nseeds = {seeds}\ncpu_per_run = 1\n[base]\nworld = {{ vehicles = {vehicles} }}\n'
        f"clock = {{ duration_s = {duration_s} }}\nview = {{ record = false }}\n"
        '[[variants]]\nname = "ekf"\n[[variants]]\nname = "plain-ci"\nvehicle = { cooperation = { fusion = "ci" } }\n'
    )
    return path


def _campaign(grid: Path, out: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, "campaign", str(grid), "--out", str(out), *args], capture_output=True, text=True)


def _outputs(folder: Path) -> dict[str, str]:
    """Hash of every run's metrics.csv and summary.json (its name taken out, as the golden runs do)."""
    out = {}
    for path in sorted(list(folder.glob("*/metrics.csv")) + list(folder.glob("*/summary.json"))):
        data = path.read_bytes()
        if path.name == "summary.json":
            summary = json.loads(data)
            summary.pop("name", None)
            data = json.dumps(summary, sort_keys=True).encode()
        out[path.relative_to(folder).as_posix()] = hashlib.sha256(data).hexdigest()
    return out


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _wait_until(predicate) -> None:
    """Poll until ``predicate`` holds, however long that takes: no deadline of its own (a run that
    never gets there is stopped by pytest-timeout, the suite's guard against hanging)."""
    while not predicate():
        time.sleep(0.2)


def _left_running(folder: Path) -> list[int]:
    """Processes of the campaign's runs still alive (their command lines name the campaign folder)."""
    return [pid for pid in processes_matching(f"{folder}/") if pid != os.getpid()]


@pytest.fixture(scope="module")
def sequential(tmp_path_factory):
    out = tmp_path_factory.mktemp("sequential")
    grid = _grid(out, "grid", seeds=3, duration_s=6)
    result = _campaign(grid, out, "--workers", "1")
    assert result.returncode == 0, result.stdout + result.stderr
    return out / "grid"


@contextlib.contextmanager
def _cluster(*worker_flags: str, resources: bool = True):
    """A scheduler and two workers, started with the stock `dask` commands (offering one ``swarm``
    each unless not ``resources``); (its address, the workers)."""
    port = _free_port()
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    scheduler = subprocess.Popen(
        [DASK, "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"], **quiet
    )
    worker = [DASK, "worker", f"tcp://127.0.0.1:{port}", "--nthreads", "1", "--no-dashboard"]
    worker += ["--resources", "swarm=1"] if resources else []
    workers = [subprocess.Popen([*worker, *worker_flags], start_new_session=True, **quiet) for _ in range(2)]
    try:
        yield f"tcp://127.0.0.1:{port}", workers
    finally:
        for process in [*workers, scheduler]:
            if process.poll() is None:
                process.terminate()
                process.wait()


def test_a_scheduler_and_two_stock_workers_fly_the_grid_as_one_worker_does(sequential, tmp_path):
    with _cluster() as (address, _):
        grid = _grid(tmp_path, "grid", seeds=3, duration_s=6)
        result = _campaign(grid, tmp_path, "--scheduler", address)
        assert result.returncode == 0, result.stdout + result.stderr
    flown = tmp_path / "grid"
    assert len(_outputs(flown)) == 12 and _outputs(flown) == _outputs(sequential)  # 6 runs, in any order
    rows = [json.loads(p.read_text()) for p in flown.glob("*/row.json")]
    assert all(r["status"] == "complete" for r in rows) and len(rows) == 6
    assert (flown / "results.parquet").is_file() and _left_running(flown) == []


def test_workers_started_without_the_swarm_resource_are_a_one_line_error_naming_the_fix(tmp_path):
    """Tasks no worker may run would wait for ever in Dask's no-worker state: the campaign says so."""
    with _cluster(resources=False) as (address, _):
        result = _campaign(_grid(tmp_path, "grid", seeds=1, duration_s=6), tmp_path, "--scheduler", address)
    assert result.returncode == 1, result.stdout + result.stderr
    assert "Traceback" not in result.stderr and result.stderr.count("\n") == 1, result.stderr
    assert "--resources swarm=1" in result.stderr and "no Dask worker" in result.stderr
    assert not list((tmp_path / "grid").glob("*/row.json"))


def test_a_worker_killed_in_the_middle_leaves_its_runs_to_the_other_and_nothing_running(tmp_path):
    grid, folder = _grid(tmp_path, "grid", seeds=3, duration_s=20), tmp_path / "grid"
    with _cluster("--no-nanny") as (address, workers):
        campaign = subprocess.Popen(
            [*CLI, "campaign", str(grid), "--out", str(tmp_path), "--scheduler", address],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        _wait_until(lambda: len(list(folder.glob("*/metrics.csv"))) >= 2)  # two runs flying
        os.kill(workers[0].pid, signal.SIGKILL)  # the worker alone: what it started must die with it
        output, _ = campaign.communicate()
    assert campaign.returncode == 0, output
    rows = [json.loads(p.read_text()) for p in folder.glob("*/row.json")]
    assert len(rows) == 6 and all(r["status"] == "complete" for r in rows), output
    _wait_until(lambda: _left_running(folder) == [])  # their processes go, however loaded the machine
    assert _left_running(folder) == []


def test_ctrl_c_leaves_nothing_running_and_the_same_command_resumes(tmp_path):
    grid = _grid(tmp_path, "grid", seeds=3, duration_s=30)
    command = [*CLI, "campaign", str(grid), "--out", str(tmp_path), "--workers", "2"]
    first = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    folder = tmp_path / "grid"
    _wait_until(lambda: len(list(folder.glob("*/metrics.csv"))) >= 2)  # two runs flying
    first.send_signal(signal.SIGINT)
    output, _ = first.communicate()
    assert first.returncode != 0, output  # stopped: not every run flown
    _wait_until(lambda: _left_running(folder) == [])
    assert _left_running(folder) == [], output
    done_before = {
        p.parent.name for p in folder.glob("*/row.json") if json.loads(p.read_text())["status"] == "complete"
    }
    again = subprocess.run(command, capture_output=True, text=True)
    assert again.returncode == 0, again.stdout + again.stderr
    assert f"({len(done_before)} from before)" in again.stdout
    rows = [json.loads(p.read_text()) for p in folder.glob("*/row.json")]
    assert len(rows) == 6 and all(r["status"] == "complete" for r in rows)


def test_twice_as_many_runs_as_cores_at_once_do_not_hear_each_other(tmp_path):
    """Each run's ground station scores only its own vehicles and refuses nothing: no run reached
    another's bus (its own router and ports, scouting off)."""
    at_once = 2 * len(os.sched_getaffinity(0))
    grid = _grid(tmp_path, "crowd", seeds=at_once // 2, duration_s=10, vehicles=3)
    result = _campaign(grid, tmp_path, "--workers", str(at_once))
    assert result.returncode == 0, result.stdout + result.stderr
    for summary_path in (tmp_path / "crowd").glob("*/summary.json"):
        summary = json.loads(summary_path.read_text())
        assert summary["status"] == "complete" and sorted(summary["vehicles"]) == ["1", "2", "3"]
        assert summary["events"].get("vehicle_joined") == 3, summary_path  # nobody else's vehicle came
        rejected = summary["rejected"]["by_reason"]
        assert not any(rejected.values()), (summary_path, rejected)
