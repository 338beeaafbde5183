"""`swarm up`: start a router, the ground station, the world and N vehicles as subprocesses,
watch them, and shut everything down cleanly on Ctrl-C/SIGTERM or when the run ends.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from bus.config import SwarmConfig
from bus.errors import SwarmlocError

SHUTDOWN_GRACE_S = 4.0


class ChildFailed(SwarmlocError):
    """A process of the swarm failed to start or died."""


@dataclass
class Child:
    name: str
    process: subprocess.Popen
    log_path: Path
    essential: bool

    def tail(self, lines: int = 8) -> str:
        try:
            text = self.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return "(no log)"
        return "\n".join(text[-lines:]) or "(empty log)"


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_for_port(port: int, timeout_s: float, router: Child) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if router.process.poll() is not None:
            raise ChildFailed(f"router exited with {router.process.returncode}:\n{router.tail()}")
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise ChildFailed(f"router did not listen on port {port} within {timeout_s:g} s")


def unique_run_dir(out: Path, name: str) -> Path:
    candidate, n = out / name, 1
    while candidate.exists():
        n += 1
        candidate = out / f"{name}-{n}"
    candidate.mkdir(parents=True)
    return candidate


class Swarm:
    """The set of child processes of one run."""

    def __init__(self, config: SwarmConfig, run_dir: Path, show_progress: bool) -> None:
        self.config, self.run_dir, self.show_progress = config, run_dir, show_progress
        self.children: list[Child] = []
        (run_dir / "logs").mkdir(exist_ok=True)

    def spawn(self, name: str, args: list[str], *, essential: bool, inherit_stdout: bool = False) -> Child:
        log_path = self.run_dir / "logs" / f"{name}.log"
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        with log_path.open("ab") as log:
            process = subprocess.Popen([sys.executable, "-m", "groundstation.cli", *args], env=env,
                                       stdout=None if inherit_stdout else log, stderr=log,
                                       stdin=subprocess.DEVNULL, start_new_session=True)
        child = Child(name, process, log_path, essential)
        self.children.append(child)
        return child

    def start(self) -> None:
        config_path = str(self.run_dir / "config.json")
        port = int(self.config.bus.connect[0].rsplit(":", 1)[1])
        router = self.spawn("router", ["router", "--listen", f"tcp/127.0.0.1:{port}"], essential=True)
        wait_for_port(port, 15.0, router)
        gs_args = ["gs", "--config", config_path, "--run-dir", str(self.run_dir)]
        self.spawn("groundstation", gs_args + ([] if self.show_progress else ["--quiet"]), essential=True,
                   inherit_stdout=self.show_progress)
        for vid in range(1, self.config.world.vehicles + 1):
            self.spawn(f"vehicle-{vid}", ["vehicle", "--config", config_path, "--id", str(vid)], essential=False)
        self.spawn("world", ["sim", "--config", config_path], essential=True)

    def watch(self, stop: threading.Event) -> list[str]:
        """Wait for the ground station to finish; returns failure reports of children that died."""
        failures: list[str] = []
        gs = next(c for c in self.children if c.name == "groundstation")
        reported: set[str] = set()
        while not stop.is_set() and gs.process.poll() is None:
            for child in self.children:
                code = child.process.poll()
                if code not in (None, 0) and child.name not in reported and child is not gs:
                    reported.add(child.name)
                    failures.append(f"{child.name} died with exit status {code}; last log lines:\n{child.tail()}")
                    if child.essential:
                        return failures
            stop.wait(0.1)
        if gs.process.returncode not in (None, 0):
            failures.append(f"groundstation exited with status {gs.process.returncode}:\n{gs.tail()}")
        return failures

    def shutdown(self) -> None:
        """SIGTERM everything (ground station last), then SIGKILL what is left after the grace period."""
        ordered = [c for c in self.children if c.name != "groundstation"] + \
                  [c for c in self.children if c.name == "groundstation"]
        ordered = [c for c in ordered if c.name != "router"] + [c for c in ordered if c.name == "router"]
        deadline = time.monotonic() + SHUTDOWN_GRACE_S
        for child in ordered:
            if child.process.poll() is None:
                child.process.send_signal(signal.SIGTERM)
        for child in ordered:
            try:
                child.process.wait(timeout=max(0.1, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                child.process.kill()
                child.process.wait()


def launch(config: SwarmConfig, out: Path, *, show_progress: bool, stop: threading.Event) -> tuple[Path, list[str]]:
    """Run one swarm to completion; returns the run directory and failure reports."""
    port = free_port()
    config = config.model_copy(update={"bus": config.bus.model_copy(
        update={"mode": "client", "connect": (f"tcp/127.0.0.1:{port}",), "listen": ()})})
    run_dir = unique_run_dir(out, config.name)
    config.dump(run_dir / "config.json")
    swarm = Swarm(config, run_dir, show_progress)
    try:
        swarm.start()
        failures = swarm.watch(stop)
    finally:
        swarm.shutdown()
    return run_dir, failures
