"""Where a run's recording goes and how it starts (groundstation.recording): ``run.mcap``, or
``run.<n>.mcap`` after a ground station's restart (an MCAP file cannot be appended to), the live
view's server, and the terrain model under a camera swarm (written by the launcher)."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from groundstation.recording import Recording

log = logging.getLogger("swarmloc.groundstation")
TERRAIN_MODEL = "terrain.glb"


def recording_path(run_dir: Path) -> Path:
    """``run.mcap``, or ``run.<n>.mcap`` when a previous ground station of this run left one."""
    path, n = run_dir / "run.mcap", 0
    while path.exists():
        n += 1
        path = run_dir / f"run.{n}.mcap"
    return path


def open_recording(run_dir: Path, view: Any, vehicles: int = 0) -> Recording | None:
    """The recording a run's ``view`` config asks for (None: neither run.mcap nor a live view), with
    the channels of ``vehicles`` vehicles made at once. A live view that cannot start (its port taken
    since the launcher checked) is logged, not fatal: the run and its recording go on."""
    if not (view.record or view.live):
        return None
    try:
        recording = Recording(recording_path(run_dir) if view.record else None, vehicles)
    except OSError as exc:  # a read-only or vanished run directory: the run goes on without run.mcap
        log.error("run.mcap cannot be written in %s: %s; the run goes on without it", run_dir, exc)
        return None
    terrain = run_dir / TERRAIN_MODEL
    if terrain.is_file():
        recording.terrain(terrain.read_bytes())
    if view.live:
        try:
            recording.serve(view.live_host, view.live_port, view.live_backlog)
            log.info("live view: ws://%s:%d (Foxglove or Lichtblick: open connection)", view.live_host, view.live_port)
        except Exception as exc:  # the SDK raises its own error types for a bind failure
            log.error("live view on %s:%d did not start: %s", view.live_host, view.live_port, exc)
    return recording
