"""How `swarm up` starts the processes of a swarm: each one forked from a server process that has
already imported what the processes run (a ``multiprocessing`` forkserver with ``PRELOAD``), instead
of a fresh interpreter importing everything again for every vehicle. The forkserver never opens a
zenoh session and starts no thread (one BLAS thread: OpenBLAS starts no pool), so every child is
forked before any zenoh session exists, as the zenoh rules ask; each child opens its own. The
forkserver lives as long as the command that started it, so an experiment's runs share it.

A child runs the `swarm` command line it is given (``swarm vehicle --config ... --id 3``) in a
process group of its own within `swarm up`'s session (``own_process_group``), with its own
environment (its logins and keys), its output in its log file, and that command line as its process
title (``ps`` and /proc show it). ``SWARMLOC_FORKSERVER=0`` starts plain subprocesses (``python -m
cli ...``) instead, each in a process group of its own too."""

from __future__ import annotations

import atexit
import multiprocessing
import multiprocessing.connection
import os
import runpy
import signal
import subprocess
import sys
import threading
from pathlib import Path

from bus.process import die_with_parent

PRELOAD = (
    "cli.main",
    "bus.session",
    "zenoh",
    "vehicle.process.loops",
    "vehicle.estimators.ekf",
    "sim.node",
    "groundstation.station_loop",
)
ONE_THREAD = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}


class Forked:
    """A forked child with the part of ``subprocess.Popen``'s interface the launcher uses."""

    def __init__(self, process: multiprocessing.process.BaseProcess) -> None:
        self._process = process
        self.pid = process.pid

    @property
    def returncode(self) -> int | None:
        return self._process.exitcode

    @property
    def sentinel(self) -> int:
        """Readable once the child has ended (multiprocessing.connection.wait)."""
        return self._process.sentinel

    def poll(self) -> int | None:
        return self._process.exitcode

    def wait(self, timeout: float | None = None) -> int:
        self._process.join(timeout)
        if self._process.exitcode is None:
            raise subprocess.TimeoutExpired(f"pid {self.pid}", timeout or 0.0)
        return self._process.exitcode

    def send_signal(self, sig: int) -> None:
        if self._process.exitcode is None:
            try:
                os.kill(self.pid, sig)
            except ProcessLookupError:
                pass

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


def start(args: list[str], env: dict[str, str], log_path: Path, *, inherit_stdout: bool) -> Forked | subprocess.Popen:
    """Start ``swarm <args>`` as a child process with environment ``env``, its output appended to
    ``log_path`` (stdout to the terminal when ``inherit_stdout``)."""
    if os.environ.get("SWARMLOC_FORKSERVER", "1") == "0":
        with log_path.open("ab") as log:
            return subprocess.Popen(
                [sys.executable, "-m", "cli", *args],
                env=env,
                stdout=None if inherit_stdout else log,
                stderr=log,
                stdin=subprocess.DEVNULL,
                process_group=0,
            )
    process = _context().Process(
        target=_child, args=(list(args), dict(env), str(log_path), inherit_stdout), daemon=True
    )
    process.start()
    return Forked(process)


def wait_for_any(processes: list, stop: threading.Event, timeout_s: float) -> None:
    """Return when one of ``processes`` ends, ``stop`` is set or ``timeout_s`` is over, whichever is
    first (forked children end the wait as they exit; subprocesses only at the timeout)."""
    sentinels = [p.sentinel for p in processes if isinstance(p, Forked)]
    if not sentinels or stop.is_set():
        stop.wait(timeout_s)
        return
    multiprocessing.connection.wait(sentinels, timeout_s)


def warm_up() -> None:
    """Start the forkserver now (it returns at once), so that it imports ``PRELOAD`` while this
    process imports the rest of what it runs: `swarm up` calls it first thing (cli.entry)."""
    if os.environ.get("SWARMLOC_FORKSERVER", "1") != "0":
        _context()


def _context() -> multiprocessing.context.BaseContext:
    """The forkserver context, its server started with ``PRELOAD`` imported and one BLAS thread
    (stopped and waited for when this process exits: ``_stop_forkserver``)."""
    from multiprocessing import forkserver

    context = multiprocessing.get_context("forkserver")
    if forkserver._forkserver._forkserver_pid is None:
        atexit.register(_stop_forkserver)
    context.set_forkserver_preload(list(PRELOAD))
    saved = {key: os.environ.get(key) for key in ONE_THREAD}
    os.environ.update(ONE_THREAD)  # the forkserver's own environment, read as it starts
    try:
        forkserver.ensure_running()
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value
    return context


def _stop_forkserver() -> None:
    """Stop the forkserver and wait for it, so that the CPU time of the children it reaped counts in
    this process's children's usage (what `time` and the benchmarks read). ``ForkServer._stop`` is
    the standard library's own way to do it (its tests use it)."""
    from multiprocessing import forkserver

    stop = getattr(forkserver._forkserver, "_stop", None)
    if stop is not None:
        stop()


def own_process_group() -> None:
    """Lead a process group of one's own and stay in the parent's session. A terminal's Ctrl-C reaches
    its foreground group, `swarm up`, which stops the swarm in order; a write to the terminal from
    this background group is let through (SIGTTOU ignored). The session is shared on purpose: Linux
    shares the cores between sessions before it weighs nice values, so the whole swarm is one session
    beside the machine's other work, and the lower priority of the world and the ground station in
    lockstep puts them behind the swarm's own vehicles only, never behind other sessions
    (docs/decisions/scale.md, Beside other work)."""
    os.setpgid(0, 0)
    signal.signal(signal.SIGTTOU, signal.SIG_IGN)


def _child(args: list[str], env: dict[str, str], log_path: str, inherit_stdout: bool) -> None:
    """In the forked child: a process group, title, environment and output of its own, then the command."""
    import setproctitle

    setproctitle.setproctitle(" ".join(["swarm", *args]))  # before the environment changes: it moves it
    die_with_parent()  # a forkserver that ends (its command killed) takes its children with it
    own_process_group()
    os.environ.clear()
    os.environ.update(env)
    log = os.open(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    if not inherit_stdout:
        os.dup2(log, 1)
    os.dup2(log, 2)
    os.close(log)
    sys.stdout.reconfigure(line_buffering=True)
    sys.stderr.reconfigure(line_buffering=True)
    sys.argv = ["swarm", *args]
    try:  # what `python -m cli ARGS` runs (the CLI's modules are preloaded), as the subprocess path does
        runpy.run_module("cli", run_name="__main__", alter_sys=True)
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
