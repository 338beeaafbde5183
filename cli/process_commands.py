"""The `swarm` commands that run one process of a swarm: `router`, `sim` (the world), `vehicle` and
`gs` (the ground station). What `swarm up` spawns, and what a deployment (compose, several hosts)
starts one by one; registered on the `swarm` app by ``cli.main``."""

from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path
from typing import Optional

import typer

from bus.clock_config import ClockMode
from bus.errors import SwarmlocError
from cli.errors import fail

BACKGROUND_ROLES = ("world", "groundstation")  # off a lockstep run's critical path: the vehicles' cycles are on it
log = logging.getLogger("swarmloc.process")


def _run_node(config_path: Path, role: str, body: Callable, *, vehicle_config: bool = False) -> None:
    """Load the config, open the bus for ``role``, run ``body(bus, config, stop)``, always close."""
    from threadpoolctl import threadpool_limits

    from bus.config import load_config, load_vehicle_config
    from bus.process import lower_cpu_priority, stop_on_signals
    from bus.session import Transport, ZenohBus

    logging.basicConfig(level=logging.INFO, format=f"%(asctime)s {role} %(levelname)s %(message)s")
    stop = stop_on_signals()
    try:
        config = (load_vehicle_config if vehicle_config else load_config)(config_path)
        config = config.model_copy(update={"bus": config.bus.with_env()})
        if niceness := lower_cpu_priority(background_niceness(role, config)):  # before zenoh's threads start
            log.info("%s runs at niceness %d: the vehicles' cycles get the cores first", role, niceness)
        # one BLAS thread: a swarm runs many single-loop processes per core, and OpenBLAS threads
        # spinning in each of them starved the others (camera vehicles: 30% loop overruns)
        with threadpool_limits(limits=1), ZenohBus(config.bus, role=role, transport=Transport.from_env()) as bus:
            body(bus, config, stop)
    except SwarmlocError as exc:
        fail(str(exc))


def background_niceness(role: str, config) -> int:
    """The niceness ``role`` runs at: ``clock.background_niceness`` for the world and the ground
    station in lockstep, where the vehicles' cycles are the critical path (the world prepares the
    next tick and the ground station scores while they cycle, on the cores they leave idle); 0 (the
    default priority) otherwise (a realtime world's feeds are due on the wall clock)."""
    if role in BACKGROUND_ROLES and config.clock.mode is ClockMode.LOCKSTEP:
        return config.clock.background_niceness
    return 0


def router(
    listen: list[str] = typer.Option(["tcp/0.0.0.0:7447"], help="zenoh endpoint(s) to listen on (tcp/... or tls/...)"),
    connect: list[str] = typer.Option([], help="other routers to join (multi-host deployments)"),
    credentials: Optional[Path] = typer.Option(None, help="user:password lines; logins become mandatory"),
    acl: bool = typer.Option(True, help="with --credentials: enforce the swarm's access control (bus.access)"),
    prefix: str = typer.Option("swarm", help="key prefix the access control protects"),
    tls_cert: Optional[Path] = typer.Option(None, help="PEM certificate for tls/ endpoints"),
    tls_key: Optional[Path] = typer.Option(None, help="PEM private key for tls/ endpoints"),
) -> None:
    """Run a zenoh router (what vehicles, world and ground station connect to)."""
    from bus.access import acl_policy
    from bus.process import stop_on_signals
    from bus.router import run_router
    from bus.secrets import credential_users
    from bus.session import Transport

    try:
        base = Transport.from_env()
        if credentials is not None and not credentials.is_file():
            fail(f"credentials file {credentials} does not exist")
        users = credential_users(credentials) if credentials else []
    except SwarmlocError as exc:
        fail(str(exc))
    if (tls_cert is None) != (tls_key is None):
        fail("--tls-cert and --tls-key go together")
    transport = Transport(
        user=base.user or ("router" if credentials else None),
        password=base.password or (_router_password(credentials) if credentials else None),
        tls_root_ca=base.tls_root_ca,
        tls_certificate=str(tls_cert) if tls_cert else None,
        tls_private_key=str(tls_key) if tls_key else None,
        credentials_file=str(credentials) if credentials else None,
        acl=acl_policy(prefix, users) if credentials and acl else None,
    )
    try:
        run_router(tuple(listen), stop_on_signals(), connect=tuple(connect), transport=transport)
    except Exception as exc:  # zenoh reports bad endpoints, certificates and configs as ZError
        fail(f"router: {str(exc).split(' at ')[0]}")


def _router_password(credentials: Path) -> str:
    """The router's own password: the `router:` line of the credentials file (or any value)."""
    for line in credentials.read_text().splitlines():
        if line.startswith("router:"):
            return line.split(":", 1)[1]
    return "router"


def sim(config: Path = typer.Option(..., help="swarm config JSON")) -> None:
    """Run the world process: truth, sensor feeds and the clock. Exits non-zero when the run ended
    early (the ground station was gone for too long)."""
    from sim.node import run_world

    def body(bus, cfg, stop) -> None:
        node = run_world(bus, cfg, stop)
        if node.status == "groundstation-lost":
            raise SwarmlocError(f"the ground station was gone for {cfg.clock.gone_timeout_s:g} s; run ended early")

    _run_node(config, "world", body)


def vehicle(
    config: Path = typer.Option(..., help="the vehicle's own config JSON (vehicle.json of a run)"),
    id: str = typer.Option(..., "--id", help="vehicle id (MAVLink sysid, 1-250), or auto: claim one from the swarm"),
    restarts: int = typer.Option(0, min=0, max=255, help="how often this vehicle was started before (reset_counter)"),
) -> None:
    """Run one vehicle process: the fixed-rate estimator loop. Logs in as $SWARMLOC_ZENOH_USER and
    signs its MAVLink stream with its own key ($SWARMLOC_MAVLINK_KEY or $SWARMLOC_MAVLINK_KEY_FILE).
    With --id auto (login `enroll`) the ground station assigns the id (unique, even for vehicles
    starting together; the same again after a restart), keyed by $SWARMLOC_VEHICLE_NAME or the host
    name, and hands over the vehicle's own login and key."""
    from bus.keys import parse_vehicle_id
    from bus.secrets import signing_key_from_env
    from vehicle.process.loops import run_vehicle

    if id != "auto" and parse_vehicle_id(id) is None:
        fail(f"--id must be 1-250 or auto, got {id!r}")

    def body(bus, cfg, stop) -> None:
        if id != "auto":
            run_vehicle(bus, cfg, int(id), stop, restarts=restarts, signing_key=signing_key_from_env())
            return
        reply = _claim_id(bus, stop)
        if reply is None:
            return
        if not reply.signing_key:  # an insecure swarm: no secrets of its own
            run_vehicle(bus, cfg, reply.vehicle_id, stop, restarts=reply.restarts, signing_key=signing_key_from_env())
            return
        from bus.secrets import vehicle_user
        from bus.session import Transport, ZenohBus

        bus.close()  # the enroll login may do nothing else
        own = Transport(
            user=vehicle_user(reply.vehicle_id),
            password=reply.zenoh_password,
            tls_root_ca=Transport.from_env().tls_root_ca,
        )
        with ZenohBus(cfg.bus, role="vehicle", transport=own) as own_bus:
            run_vehicle(
                own_bus,
                cfg,
                reply.vehicle_id,
                stop,
                restarts=reply.restarts,
                signing_key=bytes.fromhex(reply.signing_key),
            )

    _run_node(config, "vehicle", body, vehicle_config=True)


def _claim_id(bus, stop, timeout_s: float = 120.0):
    """Ask the ground station for this host's vehicle id until it answers (it may start later)."""
    import os
    import socket
    import time

    from bus.claims import ClaimReply, ClaimRequest
    from bus.plan import decode_json, encode_json

    host = os.environ.get("SWARMLOC_VEHICLE_NAME") or socket.gethostname()
    payload = encode_json(ClaimRequest(host=host))
    deadline = time.monotonic() + timeout_s
    log = logging.getLogger("swarmloc.vehicle")
    while not stop.is_set() and time.monotonic() < deadline:
        for raw in bus.get(bus.keys.claim(), payload, 2.0):
            reply = decode_json(ClaimReply, raw)
            if reply.ok:
                log.info("%s claimed vehicle id %d (restarts %d)", host, reply.vehicle_id, reply.restarts)
                return reply
            if "alive" not in reply.error:
                raise SwarmlocError(f"no vehicle id for {host}: {reply.error}")
            log.warning("%s: %s; asking again", host, reply.error)  # our previous self has not left yet
        time.sleep(0.5)
    if stop.is_set():
        return None
    raise SwarmlocError(f"no ground station answered the id claim of {host} within {timeout_s:g} s")


def gs(
    config: Path = typer.Option(..., help="swarm config JSON"),
    run_dir: Path = typer.Option(..., help="run directory to write (appended if it exists)"),
    quiet: bool = typer.Option(False, help="no live display"),
    mavlink_out: Optional[str] = typer.Option(
        None, help="forward every vehicle's MAVLink to a GCS: udpout:HOST[:PORT] (port 14550)"
    ),
) -> None:
    """Run the ground station: own the fault plan, score estimates against truth and write the run
    directory. With the swarm's master key ($SWARMLOC_MAVLINK_KEY[_FILE]) it accepts only MAVLink
    signed with each vehicle's own key, and hands vehicles that claim an id their secrets."""
    from bus.secrets import signing_key_from_env
    from groundstation.display import live_display
    from groundstation.mavlink_out import MavlinkForwarder
    from groundstation.station_loop import run_groundstation

    def body(bus, cfg, stop) -> None:
        forwarder = MavlinkForwarder(mavlink_out) if mavlink_out else None
        with live_display(cfg.clock.mode, cfg.clock.duration_s, quiet) as on_progress:
            run_groundstation(
                bus, cfg, run_dir, stop, on_progress, master_key=signing_key_from_env(), forwarder=forwarder
            )

    _run_node(config, "groundstation", body)


COMMANDS = (router, sim, vehicle, gs)
