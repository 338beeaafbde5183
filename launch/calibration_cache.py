"""A replay's calibration, remembered: ``swarm replay mrclam`` fits the datasheet on an interval of the
data set before it replays (sim.mrclam_calibration, then four known-map replays held out inside the
interval for the unmodelled sigma: launch.replay_setup.held_out_sigma), 10-15 s for five robots and
two minutes, on every run of a campaign's grid as on the first.

The calibration is a function of the data, what it is asked (the robots, the interval, and the
seed of the held-out replays' launch priors: launch.replay_setup.calibration_inputs) and the code
alone, so it is kept as the calibration file ``swarm replay calibrate`` would write
(sim.mrclam_calibration_file: it reads back to the same numbers, bit for bit) under a key of all of
them: the data set's arrays, what it is asked, every source file of the packages the calibration
runs (bus, sim, vehicle, launch), and the versions of Python, numpy and scipy. Any change to one of
them is another key; a file that does not read back is calibrated again. The folder is
``$SWARMLOC_CACHE/calibrations`` (default ``$XDG_CACHE_HOME/swarmloc``, else ``~/.cache/swarmloc``);
``SWARMLOC_CACHE=off`` calibrates every time. Replays that start together (a campaign's runs) take
turns on a lock per key: the first calibrates, the others read what it kept.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import logging
import os
import sys
import tempfile
import time
from collections.abc import Callable, Mapping
from importlib.metadata import version
from pathlib import Path

import numpy as np

from bus.errors import ConfigError
from sim.mrclam import MrclamData
from sim.mrclam_calibration_file import CalibrationFile, read_calibration, write_calibration

log = logging.getLogger("swarmloc.replay")
PACKAGES = ("bus", "sim", "vehicle", "launch")  # what a calibration runs (held-out replays in process)
LOCK_WAIT_S = 600.0  # how long a replay waits for another that calibrates the same key


def cache_folder(environ: Mapping[str, str] = os.environ) -> Path | None:
    """Where calibrations are kept (module docstring), or None when ``SWARMLOC_CACHE=off``."""
    chosen = environ.get("SWARMLOC_CACHE", "")
    if chosen.lower() == "off":
        return None
    if chosen:
        return Path(chosen) / "calibrations"
    base = environ.get("XDG_CACHE_HOME", "") or str(Path.home() / ".cache")
    return Path(base) / "swarmloc" / "calibrations"


def remembered(
    data: MrclamData, asked: str, calibrate: Callable[[], CalibrationFile], folder: Path | None
) -> CalibrationFile:
    """The calibration of ``data`` for ``asked`` (a text naming everything else ``calibrate`` reads):
    read from ``folder`` under its key, else ``calibrate()`` and kept there (None: not kept), one
    replay at a time per key. A folder that cannot be written costs the next run a calibration,
    nothing else."""
    if folder is None:
        return calibrate()
    key = calibration_key(data, asked)
    path = folder / f"{key}.json"
    with _exclusive(folder / f"{key}.lock"):  # the replays of a campaign that start together: one calibrates
        if path.is_file():
            try:
                kept = read_calibration(path)
                log.info("calibration kept in %s (%s)", path, asked)
                return kept
            except ConfigError as exc:
                log.warning("%s; calibrating again", exc)
        calibration = calibrate()
        _keep(calibration, path)
        return calibration


def _keep(calibration: CalibrationFile, path: Path) -> None:
    """Write ``calibration`` to ``path`` whole or not at all (a partial file never stays behind)."""
    partial = None
    try:
        with tempfile.NamedTemporaryFile("w", dir=path.parent, suffix=".tmp", delete=False) as handle:
            partial = Path(handle.name)
        write_calibration(partial, calibration)
        os.replace(partial, path)
    except OSError as exc:
        log.warning("calibration not kept in %s (%s): the next replay calibrates again", path.parent, exc)
        if partial is not None:
            partial.unlink(missing_ok=True)


@contextlib.contextmanager
def _exclusive(lock: Path, wait_s: float = LOCK_WAIT_S):
    """Hold ``lock`` (an flock, released when the holder ends however it ends) while the block runs;
    after ``wait_s`` without it, or where it cannot be taken, the block runs all the same."""
    try:
        lock.parent.mkdir(parents=True, exist_ok=True)
        handle = lock.open("a")
    except OSError:
        yield
        return
    with handle:
        deadline = time.monotonic() + wait_s
        while True:
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except OSError:
                if time.monotonic() > deadline:
                    log.warning("%s still held after %g s: calibrating alongside its holder", lock, wait_s)
                    break
                time.sleep(0.1)
        yield  # the lock goes with the handle's close


def calibration_key(data: MrclamData, asked: str) -> str:
    """A hex digest of everything a calibration depends on (module docstring)."""
    digest = hashlib.sha256(asked.encode())
    digest.update(data_fingerprint(data).encode())
    digest.update(code_fingerprint().encode())
    return digest.hexdigest()[:32]


def data_fingerprint(data: MrclamData) -> str:
    """A digest of a data set's contents: its start, surveyed landmarks and every robot's logs."""
    digest = hashlib.sha256(repr(float(data.start_s)).encode())
    digest.update(_array_bytes(data.landmarks))
    for robot in sorted(data.robots):
        log_ = data.robots[robot]
        digest.update(repr((robot, int(log_.unknown_barcodes))).encode())
        for table in (log_.groundtruth, log_.odometry, log_.sightings):
            digest.update(_array_bytes(table))
    return digest.hexdigest()


@functools.cache
def code_fingerprint() -> str:
    """A digest of the source of ``PACKAGES`` and of the Python, numpy and scipy versions (computed
    once per process: the source does not change under a running program)."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256(repr((sys.version, version("numpy"), version("scipy"))).encode())
    for package in PACKAGES:
        for source in sorted((root / package).rglob("*.py")):
            digest.update(str(source.relative_to(root)).encode())
            digest.update(source.read_bytes())
    return digest.hexdigest()


def _array_bytes(table: np.ndarray) -> bytes:
    """The array's shape, dtype and values, as bytes."""
    table = np.ascontiguousarray(table)
    return repr((table.shape, table.dtype.str)).encode() + table.tobytes()
