"""The `swarm` command: run a whole swarm (`up`) or one process of it (`router`, `sim`, `vehicle`, `gs`)."""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Callable, Optional

import typer

from bus.errors import SwarmlocError
from groundstation.cli_errors import REPORT_HELP, fail
from groundstation.experiment_commands import experiment_app
from groundstation.fault_commands import fault_app
from groundstation.replay_commands import replay_app

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="swarmloc: multi-process swarm localization over zenoh, with MAVLink 2 state packets.")
app.add_typer(fault_app, name="fault")
app.add_typer(experiment_app, name="experiment")
app.add_typer(replay_app, name="replay")


def _run_node(config_path: Path, role: str, body: Callable, *, vehicle_config: bool = False) -> None:
    """Load the config, open the bus for ``role``, run ``body(bus, config, stop)``, always close."""
    from bus.config import load_config, load_vehicle_config
    from bus.process import stop_on_signals
    from bus.session import Transport, ZenohBus
    from threadpoolctl import threadpool_limits

    logging.basicConfig(level=logging.INFO, format=f"%(asctime)s {role} %(levelname)s %(message)s")
    stop = stop_on_signals()
    try:
        config = (load_vehicle_config if vehicle_config else load_config)(config_path)
        config = config.model_copy(update={"bus": config.bus.with_env()})
        # one BLAS thread: a swarm runs many single-loop processes per core, and OpenBLAS threads
        # spinning in each of them starved the others (camera vehicles: 30% loop overruns)
        with threadpool_limits(limits=1), ZenohBus(config.bus, role=role, transport=Transport.from_env()) as bus:
            body(bus, config, stop)
    except SwarmlocError as exc:
        fail(str(exc))


@app.command()
def up(
    scenario: Optional[Path] = typer.Argument(None, help="TOML scenario (config and fault timeline); options below override it"),
    vehicles: Optional[int] = typer.Option(None, help="number of vehicles (1-250) [default: 5]"),
    duration: Optional[float] = typer.Option(None, help="simulated seconds [default: 60]"),
    mode: Optional[str] = typer.Option(None, help="lockstep (reproducible, as fast as possible) or realtime [default: lockstep]"),
    speed: Optional[float] = typer.Option(None, help="realtime only: sim seconds per wall second [default: 1]"),
    seed: Optional[int] = typer.Option(None, help="seed of trajectories and sensor noise [default: 0]"),
    tick: Optional[float] = typer.Option(None, help="sim seconds the world advances per clock tick [default: 0.5 lockstep, 0.02 realtime]"),
    out: Path = typer.Option(Path("runs"), help="parent folder of run directories"),
    name: Optional[str] = typer.Option(None, help="run directory name (a suffix is added if it exists) [default: the scenario's name, or run]"),
    quiet: bool = typer.Option(False, help="no progress display, only the final table"),
    restart: str = typer.Option("no", help="no, or on-failure: start a vehicle or the ground station again when it dies"),
    chaos: Optional[int] = typer.Option(None, help="add a random fault timeline of every kind, drawn from this seed"),
    insecure: bool = typer.Option(False, help="no zenoh logins, no access control, no MAVLink signing"),
    mavlink_out: Optional[str] = typer.Option(None, help="forward every vehicle's MAVLink to a GCS: udpout:HOST[:PORT]"),
    tls_cert: Optional[Path] = typer.Option(None, help="run the bus over TLS: the router's PEM certificate (for localhost)"),
    tls_key: Optional[Path] = typer.Option(None, help="TLS: the router's PEM private key"),
    tls_ca: Optional[Path] = typer.Option(None, help="TLS: the PEM CA that signed the certificate"),
    fault_seed: Optional[int] = typer.Option(None, help="seed of link-fault decisions (independent of --seed) [default: 1]"),
    report: bool = typer.Option(True, help=REPORT_HELP),
) -> None:
    """Start a zenoh router, the world, the ground station and N vehicles; print the RMSE table and write the report."""
    from bus.config import build_config
    from bus.process import stop_on_signals
    from groundstation.launcher import Security, launch
    from groundstation.mavlink_out import parse_udpout
    from groundstation.scenario import load_scenario, overlay

    if mode not in (None, "lockstep", "realtime"):
        fail(f"unknown mode {mode!r}: use lockstep or realtime")
    if restart not in ("no", "on-failure"):
        fail(f"unknown restart policy {restart!r}: use no or on-failure")
    tls = [tls_cert, tls_key, tls_ca]
    if any(tls) and not all(p is not None and p.is_file() for p in tls):
        fail("TLS needs --tls-cert, --tls-key and --tls-ca, all existing PEM files")
    try:
        base = load_scenario(scenario) if scenario else {}
        config = build_config(overlay(base, {"name": name, "world": {"vehicles": vehicles, "seed": seed}, "fault_seed": fault_seed,
                                             "clock": {"mode": mode, "speed": speed, "duration_s": duration, "tick_s": tick}}))
        if chaos is not None:
            config = with_chaos(config, chaos)
        if mavlink_out:
            parse_udpout(mavlink_out)
        security = Security(tls_certificate=tls_cert, tls_private_key=tls_key, tls_root_ca=tls_ca, mavlink_out=mavlink_out)
        run_dir, failures, notes = launch(config, out, show_progress=not quiet, stop=stop_on_signals(), restart=restart,
                                          secure=not insecure, security=security)
    except SwarmlocError as exc:
        fail(str(exc))
    _print_result(run_dir, failures, notes, report=report)


@app.command()
def config(
    scenario: Optional[Path] = typer.Argument(None, help="TOML scenario (config and fault timeline); options below override it"),
    out: Path = typer.Option(..., help="directory for config.json and vehicle.json (created)"),
    vehicles: Optional[int] = typer.Option(None, help="number of vehicles (1-250) [default: 5]"),
    duration: Optional[float] = typer.Option(None, help="simulated seconds [default: 60]"),
    mode: Optional[str] = typer.Option(None, help="lockstep or realtime [default: lockstep]"),
    seed: Optional[int] = typer.Option(None, help="seed of trajectories and sensor noise [default: 0]"),
) -> None:
    """Write the configs of a deployment: config.json for the world and the ground station (the whole
    scenario, seed and trajectories included) and vehicle.json for the vehicles (only what a vehicle
    needs: no seed, no trajectories, nothing that determines truth)."""
    from bus.config import build_config
    from groundstation.scenario import load_scenario, overlay

    if mode not in (None, "lockstep", "realtime"):
        fail(f"unknown mode {mode!r}: use lockstep or realtime")
    try:
        base = load_scenario(scenario) if scenario else {}
        swarm = build_config(overlay(base, {"world": {"vehicles": vehicles, "seed": seed},
                                            "clock": {"mode": mode, "duration_s": duration}}))
        out.mkdir(parents=True, exist_ok=True)
        swarm.dump(out / "config.json")
        swarm.for_vehicle().dump(out / "vehicle.json")
    except OSError as exc:
        fail(f"cannot write to {out}: {exc.strerror or exc}")
    except SwarmlocError as exc:
        fail(str(exc))
    typer.echo(f"wrote {out / 'config.json'} (world, ground station) and {out / 'vehicle.json'} (vehicles)")


def with_chaos(config, seed: int):
    """``config`` with a chaos fault timeline (every kind of fault) added to its own faults."""
    from bus.config import build_config
    from groundstation.chaos import chaos_faults

    data = config.model_dump(mode="json")
    data["faults"] = data["faults"] + chaos_faults(seed, vehicles=config.world.vehicles, duration_s=config.clock.duration_s,
                                                   spacing_m=config.world.spacing_m)
    return build_config(data)


def _print_result(run_dir: Path, failures: list[str], notes: list[str], *, report: bool = True) -> None:
    """The run's table, then its report (``report``: written now; else how to write it later); exits
    1 when a process failed, no summary was written or the report could not be."""
    from rich.console import Console

    from groundstation.display import rmse_table

    console = Console()
    for note in notes:
        console.print(f"[yellow]swarm: {note}[/yellow]", highlight=False)
    for failure in failures:
        console.print(f"[red]swarm: {failure}[/red]")
    summary_path = run_dir / "summary.json"
    if summary_path.exists():
        summary = json.loads(summary_path.read_text())
        timing_path = run_dir / "timing.json"
        timing = json.loads(timing_path.read_text()) if timing_path.exists() else None
        console.print(rmse_table(summary, timing, title=f"{summary['name']}: {summary['status']}"))
    else:
        console.print(f"[red]swarm: no summary.json was written in {run_dir}[/red]")
    console.print(f"run directory: {run_dir}")
    from groundstation.display import report_and_say

    if report:
        report_ok = report_and_say(run_dir, console)
    else:
        console.print(f"report: not written (--no-report); `swarm report {run_dir}` writes it", highlight=False)
        report_ok = True
    if failures or not summary_path.exists() or not report_ok:
        raise typer.Exit(1)


@app.command()
def report(run_dir: Path = typer.Argument(..., help="a run directory written by `swarm up` (may be partial)")) -> None:
    """Write report.html (self-contained) and report/*.png for a run directory; says what is missing."""
    from rich.console import Console

    from groundstation.display import report_and_say

    if not report_and_say(run_dir, Console()):
        raise typer.Exit(1)


@app.command()
def secrets(out: Path = typer.Option(..., help="directory for the secrets (created, owner-only)"),
            vehicles: int = typer.Option(5, min=1, max=250, help="logins and signing keys for vehicles 1..N"),
            keep: bool = typer.Option(True, help="leave an existing set alone (containers share one)"),
            enroll_out: Optional[Path] = typer.Option(None, help="also copy the enroll login (all that --id auto "
                                                              "vehicles get) to this directory")) -> None:
    """Write a fresh master MAVLink key, one zenoh password per role, a login and a signing key per
    vehicle, and the router's credentials file: what `swarm up` does for every run, for deployments
    (compose) to share."""
    import shutil

    from bus.secrets import write_secrets

    try:
        if keep and (out / "credentials.txt").exists():
            typer.echo(f"secrets in {out} exist; kept")
        else:
            write_secrets(out, vehicles=vehicles)
            typer.echo(f"secrets for {vehicles} vehicles written to {out}")
        if enroll_out is not None:
            enroll_out.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(out / "enroll.password", enroll_out / "enroll.password")
    except OSError as exc:
        fail(f"cannot write secrets to {out}: {exc.strerror or exc}")
    except SwarmlocError as exc:
        fail(str(exc))


@app.command()
def router(listen: list[str] = typer.Option(["tcp/0.0.0.0:7447"], help="zenoh endpoint(s) to listen on (tcp/... or tls/...)"),
           connect: list[str] = typer.Option([], help="other routers to join (multi-host deployments)"),
           credentials: Optional[Path] = typer.Option(None, help="user:password lines; logins become mandatory"),
           acl: bool = typer.Option(True, help="with --credentials: enforce the swarm's access control (bus.access)"),
           prefix: str = typer.Option("swarm", help="key prefix the access control protects"),
           tls_cert: Optional[Path] = typer.Option(None, help="PEM certificate for tls/ endpoints"),
           tls_key: Optional[Path] = typer.Option(None, help="PEM private key for tls/ endpoints")) -> None:
    """Run a zenoh router (what vehicles, world and ground station connect to)."""
    from bus.access import acl_policy
    from bus.process import stop_on_signals
    from bus.secrets import credential_users
    from bus.session import Transport
    from groundstation.router import run_router

    try:
        base = Transport.from_env()
        if credentials is not None and not credentials.is_file():
            fail(f"credentials file {credentials} does not exist")
        users = credential_users(credentials) if credentials else []
    except SwarmlocError as exc:
        fail(str(exc))
    if (tls_cert is None) != (tls_key is None):
        fail("--tls-cert and --tls-key go together")
    transport = Transport(user=base.user or ("router" if credentials else None),
                          password=base.password or (_router_password(credentials) if credentials else None),
                          tls_root_ca=base.tls_root_ca, tls_certificate=str(tls_cert) if tls_cert else None,
                          tls_private_key=str(tls_key) if tls_key else None,
                          credentials_file=str(credentials) if credentials else None,
                          acl=acl_policy(prefix, users) if credentials and acl else None)
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


@app.command()
def sim(config: Path = typer.Option(..., help="swarm config JSON")) -> None:
    """Run the world process: truth, sensor feeds and the clock. Exits non-zero when the run ended
    early (the ground station was gone for too long)."""
    from sim.node import run_world

    def body(bus, cfg, stop) -> None:
        node = run_world(bus, cfg, stop)
        if node.status == "groundstation-lost":
            raise SwarmlocError(f"the ground station was gone for {cfg.clock.gone_timeout_s:g} s; run ended early")

    _run_node(config, "world", body)


@app.command()
def vehicle(config: Path = typer.Option(..., help="the vehicle's own config JSON (vehicle.json of a run)"),
            id: str = typer.Option(..., "--id", help="vehicle id (MAVLink sysid, 1-250), or auto: claim one from the swarm"),
            restarts: int = typer.Option(0, min=0, max=255, help="how often this vehicle was started before (reset_counter)")) -> None:
    """Run one vehicle process: the fixed-rate estimator loop. Logs in as $SWARMLOC_ZENOH_USER and
    signs its MAVLink stream with its own key ($SWARMLOC_MAVLINK_KEY or $SWARMLOC_MAVLINK_KEY_FILE).
    With --id auto (login `enroll`) the ground station assigns the id (unique, even for vehicles
    starting together; the same again after a restart), keyed by $SWARMLOC_VEHICLE_NAME or the host
    name, and hands over the vehicle's own login and key."""
    from bus.keys import parse_vehicle_id
    from bus.secrets import signing_key_from_env
    from vehicle.loops import run_vehicle

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
        own = Transport(user=vehicle_user(reply.vehicle_id), password=reply.zenoh_password,
                        tls_root_ca=Transport.from_env().tls_root_ca)
        with ZenohBus(cfg.bus, role="vehicle", transport=own) as own_bus:
            run_vehicle(own_bus, cfg, reply.vehicle_id, stop, restarts=reply.restarts,
                        signing_key=bytes.fromhex(reply.signing_key))

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


@app.command()
def gs(config: Path = typer.Option(..., help="swarm config JSON"),
       run_dir: Path = typer.Option(..., help="run directory to write (appended if it exists)"),
       quiet: bool = typer.Option(False, help="no live display"),
       mavlink_out: Optional[str] = typer.Option(None, help="forward every vehicle's MAVLink to a GCS: udpout:HOST[:PORT] (port 14550)")) -> None:
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
            run_groundstation(bus, cfg, run_dir, stop, on_progress, master_key=signing_key_from_env(), forwarder=forwarder)

    _run_node(config, "groundstation", body)


if __name__ == "__main__":
    app()
