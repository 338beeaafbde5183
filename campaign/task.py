"""One campaign task on a Dask worker: fly one run (launch.fly) as a process of its own, within a
wall-clock timeout, and return its row (campaign.rows). The run dies with the worker (a lost worker
leaves nothing running: PR_SET_PDEATHSIG down the chain), and a timeout ends it (SIGTERM, then
SIGKILL). With no shared filesystem the run directory travels back with the row, as a tar archive."""

from __future__ import annotations

import datetime
import io
import os
import shutil
import signal
import socket
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any

from campaign.rows import ROW_FILE, run_row
from launch.runspec import RunSpec

GRACE_S = 15.0


def fly(spec_json: str, folder: str, campaign: str, timeout_s: float, shared: bool) -> dict[str, Any]:
    """Fly the run ``spec_json`` into ``folder`` (on a shared filesystem) or into a scratch folder of
    this worker whose run directory is returned as ``row["_archive"]`` (tar bytes)."""
    spec = RunSpec.from_json(spec_json)
    base = Path(folder) if shared else Path(tempfile.mkdtemp(prefix="swarmloc-campaign-"))
    base.mkdir(parents=True, exist_ok=True)
    run_dir = base / spec.name
    shutil.rmtree(run_dir, ignore_errors=True)  # a half-flown earlier attempt
    spec_file = base / f".{spec.name}.spec.json"
    spec_file.write_text(spec_json)
    started, t0 = datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"), time.monotonic()
    status, reason = _run(spec_file, base, timeout_s)
    spec_file.unlink(missing_ok=True)
    if not run_dir.is_dir():
        run_dir.mkdir(parents=True)
    row = run_row(
        spec,
        run_dir,
        campaign=campaign,
        status=status,
        exit_reason=reason,
        worker=socket.gethostname(),
        start=started,
        wall_s=time.monotonic() - t0,
    )
    (run_dir / ROW_FILE).write_text(_json(row))
    if not shared:
        row["_archive"] = _archive(run_dir)
        shutil.rmtree(base, ignore_errors=True)
    return row


def _run(spec_file: Path, base: Path, timeout_s: float) -> tuple[str, str]:
    """(status, exit reason) of ``python -m launch.fly`` on the spec, within ``timeout_s``."""
    log_path = base / f".{spec_file.name.removesuffix('.spec.json').lstrip('.')}.log"
    log = log_path.open("w")
    process = subprocess.Popen(
        [sys.executable, "-m", "launch.fly", str(spec_file), str(base)],
        stdout=log,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        start_new_session=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )
    try:
        code = process.wait(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        _end(process)
        return "failed", f"timeout after {timeout_s:g} s"
    finally:
        log.close()
    if code == 0:
        log_path.unlink(missing_ok=True)
        return "complete", ""
    tail = log_path.read_text(errors="replace").strip().splitlines()[-3:]
    return "failed", f"exit status {code}: " + " | ".join(tail)[-500:]


def _end(process: subprocess.Popen) -> None:
    """SIGTERM (the swarm shuts down in order), SIGKILL after GRACE_S."""
    process.send_signal(signal.SIGTERM)
    try:
        process.wait(timeout=GRACE_S)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def _archive(run_dir: Path) -> bytes:
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        tar.add(run_dir, arcname=run_dir.name)
    return buffer.getvalue()


def _json(row: dict[str, Any]) -> str:
    import json

    return json.dumps(row, sort_keys=True, indent=1) + "\n"
