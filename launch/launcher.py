"""`swarm up`: start a router, the ground station, the world and N vehicles as child processes
(launch.children: forked from a pre-loaded forkserver), watch them, and shut everything down cleanly
on Ctrl-C/SIGTERM or when the run ends.
"""

from __future__ import annotations

import dataclasses
import json
import os
import queue
import signal
import subprocess
import threading
import time
from pathlib import Path

from bus import messages as m
from bus.clock_config import ClockMode
from bus.config import SwarmConfig, ViewConfig
from bus.errors import ConfigError, DecodeError
from bus.kill_schedule import KillSchedule
from bus.plan import FaultPlan, decode_json
from bus.secrets import write_secrets
from bus.session import Envelope
from launch import children
from launch.child import Child, free_port, wait_for_port
from launch.run_setup import Security, unique_run_dir, write_terrain_model

SHUTDOWN_GRACE_S = 4.0
WATCH_PERIOD_S = 0.1  # the supervisor looks at the fault plan this often (a child ending wakes it at once)
# one BLAS thread per process (each child limits itself with threadpoolctl too): told before numpy is
# imported, OpenBLAS starts no thread pool at all (0.1 s of CPU less per process start); a user's
# own setting wins
CHILD_ENV = {"OPENBLAS_NUM_THREADS": "1"}
# lockstep: zenoh's runtimes folded into one worker thread in the swarm's own processes (each talks
# to one router over one link): 23 processes of 20 vehicles on two cores ran 5 % faster and spent
# 5 % less CPU. Not for the router, which serves every link, nor in realtime, where 32 vehicles'
# worst jitter had outliers with it (19 ms); a user's own ZENOH_RUNTIME wins.
ONE_ZENOH_RUNTIME = (
    "(rx: (handover: app), tx: (handover: app), net: (handover: app), acc: (handover: app), app: (worker_threads: 1))"
)
SWARM_HANDLE = "swarm.json"  # in the run directory while `swarm up` runs: how `swarm fault` finds it


class Swarm:
    """The set of child processes of one run, and the supervisor that executes kill faults and the
    restart policy (``no`` or ``on-failure``: a vehicle or ground station that dies is started again)."""

    def __init__(
        self,
        config: SwarmConfig,
        run_dir: Path,
        show_progress: bool,
        *,
        restart: str = "no",
        security: Security = Security(),
    ) -> None:
        self.config, self.run_dir, self.show_progress, self.restart = config, run_dir, show_progress, restart
        self.security = security
        self.config_path = str(run_dir / "config.json")
        self.vehicle_config_path = str(run_dir / "vehicle.json")
        self.children: list[Child] = []
        self.notes: list[str] = []
        self.restarts: dict[str, int] = {}
        self.kills = KillSchedule()
        self.kills.set_plan(config.faults)
        self.planned_dead: set[str] = set()
        self.bus = None
        self.inbox: queue.SimpleQueue = queue.SimpleQueue()
        self.now_us = 0
        (run_dir / "logs").mkdir(exist_ok=True)

    def spawn(self, name: str, args: list[str], *, essential: bool, inherit_stdout: bool = False) -> Child:
        log_path = self.run_dir / "logs" / f"{name}.log"
        secrets = self.security.env(name) if name != "router" else {}
        one_thread = name != "router" and self.config.clock.mode is ClockMode.LOCKSTEP
        runtime = {"ZENOH_RUNTIME": ONE_ZENOH_RUNTIME} if one_thread else {}
        env = {**CHILD_ENV, **runtime, **os.environ, "PYTHONUNBUFFERED": "1", **secrets}
        process = children.start(args, env, log_path, inherit_stdout=inherit_stdout)
        child = Child(name, process, log_path, essential)
        self.children = [c for c in self.children if c.name != name] + [child]
        return child

    def spawn_vehicle(self, vid: int) -> Child:
        name = f"vehicle-{vid}"
        args = [
            "vehicle",
            "--config",
            self.vehicle_config_path,
            "--id",
            str(vid),
            "--restarts",
            str(self.restarts.get(name, 0)),
        ]
        return self.spawn(name, args, essential=False)

    def spawn_groundstation(self) -> Child:
        args = ["gs", "--config", self.config_path, "--run-dir", str(self.run_dir)]
        if self.security.mavlink_out:
            args += ["--mavlink-out", self.security.mavlink_out]
        return self.spawn(
            "groundstation",
            args + ([] if self.show_progress else ["--quiet"]),
            essential=True,
            inherit_stdout=self.show_progress,
        )

    def start(self) -> None:
        port = int(self.config.bus.connect[0].rsplit(":", 1)[1])
        listen = self.config.bus.connect[0].replace("localhost", "127.0.0.1")
        router = self.spawn(
            "router",
            ["router", "--listen", listen, "--prefix", self.config.bus.prefix, *self.security.router_args()],
            essential=True,
        )
        wait_for_port(port, 15.0, router)
        self._open_supervisor_bus()
        self.spawn_groundstation()
        for vid in range(1, self.config.world.vehicles + 1):
            self.spawn_vehicle(vid)
        self.spawn("world", ["sim", "--config", self.config_path], essential=True)

    def _open_supervisor_bus(self) -> None:
        """The supervisor's own zenoh session: it follows the clock and the fault plan (kill faults)."""
        from bus.session import Transport, ZenohBus

        self.bus = ZenohBus(
            self.config.bus, role="supervisor", transport=Transport.from_env(self.security.env("supervisor"))
        )
        self.bus.subscribe(self.bus.keys.clock(), self.inbox, 8 << 10)
        self.bus.subscribe(self.bus.keys.fault_plan(), self.inbox, 1 << 20)
        self.bus.declare_token(self.bus.keys.alive("supervisor", 0))  # lockstep: the world holds for kills

    def _follow_plan(self) -> None:
        """Drain the supervisor inbox, then execute the kill faults that are due."""
        while True:
            try:
                envelope = self.inbox.get_nowait()
            except queue.Empty:
                break
            if not isinstance(envelope, Envelope):
                continue  # oversized: nothing a supervisor needs
            try:
                if envelope.key == self.bus.keys.clock():
                    self.now_us = max(self.now_us, m.decode(m.ClockTick, envelope.payload).stamp_us)
                else:
                    self.kills.set_plan(decode_json(FaultPlan, envelope.payload).faults)
            except DecodeError:
                continue
        for action, vid, fault in self.kills.due(self.now_us):
            self._execute(action, vid, fault)

    def _execute(self, action: str, vid: int, fault: str) -> None:
        name = f"vehicle-{vid}"
        child = next((c for c in self.children if c.name == name), None)
        if action == "kill":
            self.planned_dead.add(name)
            if child is not None and child.process.poll() is None:
                child.process.kill()
            self.notes.append(f"{name} killed by fault {fault} at {self.now_us * 1e-6:.2f} s")
        elif name in self.planned_dead:
            self.planned_dead.discard(name)
            self.restarts[name] = self.restarts.get(name, 0) + 1
            self.spawn_vehicle(vid)
            self.notes.append(f"{name} restarted after fault {fault} at {self.now_us * 1e-6:.2f} s")

    def watch(self, stop: threading.Event) -> list[str]:
        """Supervise until the ground station finishes; returns failure reports of children that died."""
        failures: list[str] = []
        handled: set[int] = set()
        while not stop.is_set():
            self._follow_plan()
            for child in list(self.children):
                code = child.process.poll()
                if code is None or child.process.pid in handled:
                    continue
                handled.add(child.process.pid)
                if child.name == "groundstation" and code == 0:
                    return failures
                if code == 0 or child.name in self.planned_dead:
                    continue
                report = f"{child.name} died with exit status {code}; last log lines:\n{child.tail()}"
                if self.restart == "on-failure" and (
                    child.name == "groundstation" or child.name.startswith("vehicle-")
                ):
                    self.notes.append(f"{report}\nrestarted (--restart on-failure)")
                    self.restarts[child.name] = self.restarts.get(child.name, 0) + 1
                    self.spawn_groundstation() if child.name == "groundstation" else self.spawn_vehicle(
                        int(child.name[8:])
                    )
                    continue
                failures.append(report)
                if child.essential:
                    return failures
            children.wait_for_any(
                [c.process for c in self.children if c.process.pid not in handled], stop, WATCH_PERIOD_S
            )
        return failures

    def shutdown(self) -> None:
        """SIGTERM everything (ground station last), then SIGKILL what is left after the grace period."""
        ordered = [c for c in self.children if c.name != "groundstation"] + [
            c for c in self.children if c.name == "groundstation"
        ]
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
        if self.bus is not None:
            self.bus.close()


def launch(
    config: SwarmConfig,
    out: Path,
    *,
    show_progress: bool,
    stop: threading.Event,
    restart: str = "no",
    secure: bool = True,
    security: Security = Security(),
    view: ViewConfig | None = None,
) -> tuple[Path, list[str], list[str]]:
    """Run one swarm to completion; returns the run directory, failure reports and notes (kills, restarts).

    ``secure``: fresh secrets in ``<run>/secrets`` (zenoh logins with access control, MAVLink signing).
    ``view``: instead of the config's (an experiment's runs served live, one after the other)."""
    if view is not None:
        config = config.model_copy(update={"view": view})
    terrain = config.world.terrain
    if config.sensors.camera_rate_hz and terrain and not Path(terrain).is_file():  # before any process starts
        raise ConfigError(f"terrain image {terrain} does not exist (world.terrain)")
    port = free_port()
    scheme, host = ("tls", "localhost") if security.tls_certificate else ("tcp", "127.0.0.1")
    config = config.model_copy(
        update={
            "bus": config.bus.model_copy(
                update={"mode": "client", "connect": (f"{scheme}/{host}:{port}",), "listen": ()}
            )
        }
    )
    run_dir = unique_run_dir(out, config.name)
    config.dump(run_dir / "config.json")
    config.for_vehicle().dump(run_dir / "vehicle.json")
    if config.sensors.camera_rate_hz and (config.view.record or config.view.live):
        write_terrain_model(config, run_dir)
    if secure:
        security = dataclasses.replace(
            security, secrets_dir=write_secrets(run_dir / "secrets", vehicles=config.world.vehicles)
        )
    swarm = Swarm(config, run_dir, show_progress, restart=restart, security=security)
    handle = run_dir / SWARM_HANDLE
    handle.write_text(
        json.dumps(
            {
                "connect": list(config.bus.connect),
                "prefix": config.bus.prefix,
                "pid": os.getpid(),
                "env": security.env("cli"),
            }
        )
    )
    try:
        swarm.start()
        failures = swarm.watch(stop)
    finally:
        handle.unlink(missing_ok=True)
        swarm.shutdown()
    return run_dir, failures, swarm.notes
