"""The `swarm` command: run a whole swarm (`up`) or one process of it (`router`, `sim`, `vehicle`, `gs`)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from bus.clock_config import ClockMode
from bus.errors import SwarmlocError
from cli import process_commands
from cli.campaign_commands import campaign
from cli.errors import REPORT_HELP, fail
from cli.experiment_commands import experiment_app
from cli.fault_commands import fault_app
from cli.replay_commands import replay_app
from cli.results import print_result

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="swarmloc: multi-process swarm localization over zenoh, with MAVLink 2 state packets.",
)
app.add_typer(fault_app, name="fault")
app.add_typer(experiment_app, name="experiment")
app.add_typer(replay_app, name="replay")
app.command()(campaign)


@app.command()
def up(
    scenario: Optional[Path] = typer.Argument(
        None, help="TOML scenario (config and fault timeline); options below override it"
    ),
    vehicles: Optional[int] = typer.Option(None, help="number of vehicles (1-250) [default: 5]"),
    duration: Optional[float] = typer.Option(None, help="simulated seconds [default: 60]"),
    mode: Optional[str] = typer.Option(
        None, help="lockstep (reproducible, as fast as possible) or realtime [default: lockstep]"
    ),
    speed: Optional[float] = typer.Option(None, help="realtime only: sim seconds per wall second [default: 1]"),
    seed: Optional[int] = typer.Option(None, help="seed of trajectories and sensor noise [default: 0]"),
    tick: Optional[float] = typer.Option(
        None,
        help="sim seconds the world advances per clock tick [default: lockstep 1, or 0.5 with cameras, a live view, "
        "kill faults, --restart on-failure or a truth batch too large for 1 s; realtime 0.02]",
    ),
    out: Path = typer.Option(Path("runs"), help="parent folder of run directories"),
    name: Optional[str] = typer.Option(
        None, help="run directory name (a suffix is added if it exists) [default: the scenario's name, or run]"
    ),
    quiet: bool = typer.Option(False, help="no progress display, only the final table"),
    restart: str = typer.Option(
        "no", help="no, or on-failure: start a vehicle or the ground station again when it dies"
    ),
    chaos: Optional[int] = typer.Option(None, help="add a random fault timeline of every kind, drawn from this seed"),
    insecure: bool = typer.Option(False, help="no zenoh logins, no access control, no MAVLink signing"),
    mavlink_out: Optional[str] = typer.Option(
        None, help="forward every vehicle's MAVLink to a GCS: udpout:HOST[:PORT]"
    ),
    tls_cert: Optional[Path] = typer.Option(
        None, help="run the bus over TLS: the router's PEM certificate (for localhost)"
    ),
    tls_key: Optional[Path] = typer.Option(None, help="TLS: the router's PEM private key"),
    tls_ca: Optional[Path] = typer.Option(None, help="TLS: the PEM CA that signed the certificate"),
    fault_seed: Optional[int] = typer.Option(
        None, help="seed of link-fault decisions (independent of --seed) [default: 1]"
    ),
    report: bool = typer.Option(True, help=REPORT_HELP),
    record: Optional[bool] = typer.Option(None, "--record/--no-record", help="write run.mcap [default: on]"),
    live: bool = typer.Option(False, help="serve a Foxglove WebSocket live view (docs: live view)"),
    live_host: Optional[str] = typer.Option(None, help="the live view's address [default: 127.0.0.1]"),
    live_port: Optional[int] = typer.Option(None, help="the live view's port [default: 8765]"),
    live_speed: Optional[float] = typer.Option(
        None, help="lockstep with --live: at most this many times real time, so a viewer can watch"
    ),
) -> None:
    """Start a zenoh router, the world, the ground station and N vehicles; print the RMSE table and write the report."""
    from bus.config import build_config
    from bus.process import stop_on_signals
    from groundstation.mavlink_out import parse_udpout
    from launch.launcher import launch
    from launch.live import check_live_address
    from launch.run_setup import Security
    from launch.scenario import load_scenario, overlay

    if mode not in (None, *ClockMode):
        fail(f"unknown mode {mode!r}: use lockstep or realtime")
    if restart not in ("no", "on-failure"):
        fail(f"unknown restart policy {restart!r}: use no or on-failure")
    tls = [tls_cert, tls_key, tls_ca]
    if any(tls) and not all(p is not None and p.is_file() for p in tls):
        fail("TLS needs --tls-cert, --tls-key and --tls-ca, all existing PEM files")
    try:
        base = load_scenario(scenario) if scenario else {}
        tick_given = tick is not None or "tick_s" in base.get("clock", {})
        config = build_config(
            overlay(
                base,
                {
                    "name": name,
                    "world": {"vehicles": vehicles, "seed": seed},
                    "fault_seed": fault_seed,
                    "clock": {"mode": mode, "speed": speed, "duration_s": duration, "tick_s": tick},
                    "view": {
                        "record": record,
                        "live": live or None,
                        "live_host": live_host,
                        "live_port": live_port,
                        "live_speed": live_speed,
                    },
                },
            )
        )
        if config.view.live:
            check_live_address(config.view.live_host, config.view.live_port)
        if chaos is not None:
            config = with_chaos(config, chaos, tick_given=tick_given)
        if restart == "on-failure" and not tick_given:
            config = with_restart_tick(config)
        if mavlink_out:
            parse_udpout(mavlink_out)
        security = Security(
            tls_certificate=tls_cert, tls_private_key=tls_key, tls_root_ca=tls_ca, mavlink_out=mavlink_out
        )
        run_dir, failures, notes = launch(
            config,
            out,
            show_progress=not quiet,
            stop=stop_on_signals(),
            restart=restart,
            secure=not insecure,
            security=security,
        )
    except SwarmlocError as exc:
        fail(str(exc))
    print_result(run_dir, failures, notes, report=report)


@app.command()
def config(
    scenario: Optional[Path] = typer.Argument(
        None, help="TOML scenario (config and fault timeline); options below override it"
    ),
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
    from launch.scenario import load_scenario, overlay

    if mode not in (None, *ClockMode):
        fail(f"unknown mode {mode!r}: use lockstep or realtime")
    try:
        base = load_scenario(scenario) if scenario else {}
        swarm = build_config(
            overlay(
                base, {"world": {"vehicles": vehicles, "seed": seed}, "clock": {"mode": mode, "duration_s": duration}}
            )
        )
        out.mkdir(parents=True, exist_ok=True)
        swarm.dump(out / "config.json")
        swarm.for_vehicle().dump(out / "vehicle.json")
    except OSError as exc:
        fail(f"cannot write to {out}: {exc.strerror or exc}")
    except SwarmlocError as exc:
        fail(str(exc))
    typer.echo(f"wrote {out / 'config.json'} (world, ground station) and {out / 'vehicle.json'} (vehicles)")


def with_chaos(config, seed: int, *, tick_given: bool = False):
    """``config`` with a chaos fault timeline (every kind of fault) added to its own faults; the tick
    chosen again for the new plan unless one was given (its kill faults want lockstep's short tick)."""
    from bus.config import build_config
    from launch.chaos import chaos_faults

    data = config.model_dump(mode="json")
    data["faults"] = data["faults"] + chaos_faults(
        seed, vehicles=config.world.vehicles, duration_s=config.clock.duration_s, spacing_m=config.world.spacing_m
    )
    if not tick_given:
        data["clock"]["tick_s"] = None
    return build_config(data)


def with_restart_tick(config):
    """``config`` on lockstep's short tick (0.5 s) for ``--restart on-failure``: a ground station started
    again loses the ticks it had not acknowledged, so short ones. Realtime keeps its own tick: its clock
    ticks every loop period (0.02 s), and a longer one would hand every vehicle its samples up to a tick
    late (docs/decisions/realtime-restart.md)."""
    from bus.clock_config import LOCKSTEP_RESTART_TICK_S
    from bus.config import build_config

    if config.clock.mode is not ClockMode.LOCKSTEP or config.clock.tick_s <= LOCKSTEP_RESTART_TICK_S:
        return config
    data = config.model_dump(mode="json")
    data["clock"]["tick_s"] = LOCKSTEP_RESTART_TICK_S
    return build_config(data)


@app.command()
def report(run_dir: Path = typer.Argument(..., help="a run directory written by `swarm up` (may be partial)")) -> None:
    """Write report.html (self-contained) and report/*.png for a run directory; says what is missing."""
    from rich.console import Console

    from groundstation.display import report_and_say

    if not report_and_say(run_dir, Console()):
        raise typer.Exit(1)


@app.command()
def secrets(
    out: Path = typer.Option(..., help="directory for the secrets (created, owner-only)"),
    vehicles: int = typer.Option(5, min=1, max=250, help="logins and signing keys for vehicles 1..N"),
    keep: bool = typer.Option(True, help="leave an existing set alone (containers share one)"),
    enroll_out: Optional[Path] = typer.Option(
        None, help="also copy the enroll login (all that --id auto vehicles get) to this directory"
    ),
) -> None:
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


for _command in process_commands.COMMANDS:
    app.command()(_command)


if __name__ == "__main__":
    app()
