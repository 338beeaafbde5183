"""The `swarm` command: run a whole swarm (`up`) or one process of it (`router`, `sim`, `vehicle`, `gs`)."""

from __future__ import annotations

import json
import logging
import sys
from pathlib import Path
from typing import Callable, Optional

import typer

from bus.errors import SwarmlocError
from groundstation.fault_commands import fault_app

app = typer.Typer(add_completion=False, no_args_is_help=True,
                  help="swarmloc: multi-process swarm localization over zenoh, with MAVLink 2 state packets.")
app.add_typer(fault_app, name="fault")


def _fail(message: str) -> None:
    typer.echo(f"swarm: error: {message}", err=True)
    raise typer.Exit(1)


def _run_node(config_path: Path, role: str, body: Callable) -> None:
    """Load the config, open the bus for ``role``, run ``body(bus, config, stop)``, always close."""
    from bus.config import load_config
    from bus.process import stop_on_signals
    from bus.session import ZenohBus

    logging.basicConfig(level=logging.INFO, format=f"%(asctime)s {role} %(levelname)s %(message)s")
    stop = stop_on_signals()
    try:
        config = load_config(config_path)
        with ZenohBus(config.bus.with_env(), role=role) as bus:
            body(bus, config, stop)
    except SwarmlocError as exc:
        _fail(str(exc))


@app.command()
def up(
    scenario: Optional[Path] = typer.Argument(None, help="TOML scenario (config and fault timeline); options below override it"),
    vehicles: Optional[int] = typer.Option(None, help="number of vehicles (1-250) [default: 5]"),
    duration: Optional[float] = typer.Option(None, help="simulated seconds [default: 60]"),
    mode: Optional[str] = typer.Option(None, help="lockstep (reproducible, as fast as possible) or realtime [default: lockstep]"),
    speed: Optional[float] = typer.Option(None, help="realtime only: sim seconds per wall second [default: 1]"),
    seed: Optional[int] = typer.Option(None, help="seed of trajectories and sensor noise [default: 0]"),
    tick: Optional[float] = typer.Option(None, help="sim seconds the world advances per clock tick [default: 0.02]"),
    out: Path = typer.Option(Path("runs"), help="parent folder of run directories"),
    name: Optional[str] = typer.Option(None, help="run directory name (a suffix is added if it exists) [default: the scenario's name, or run]"),
    quiet: bool = typer.Option(False, help="no progress display, only the final table"),
    restart: str = typer.Option("no", help="no, or on-failure: start a vehicle or the ground station again when it dies"),
    chaos: Optional[int] = typer.Option(None, help="add a random fault timeline of every kind, drawn from this seed"),
) -> None:
    """Start a zenoh router, the world, the ground station and N vehicles; print the RMSE table and write the report."""
    from bus.config import build_config
    from bus.process import stop_on_signals
    from groundstation.launcher import launch
    from groundstation.scenario import load_scenario, overlay

    if mode not in (None, "lockstep", "realtime"):
        _fail(f"unknown mode {mode!r}: use lockstep or realtime")
    if restart not in ("no", "on-failure"):
        _fail(f"unknown restart policy {restart!r}: use no or on-failure")
    try:
        base = load_scenario(scenario) if scenario else {}
        config = build_config(overlay(base, {"name": name, "world": {"vehicles": vehicles, "seed": seed},
                                             "clock": {"mode": mode, "speed": speed, "duration_s": duration, "tick_s": tick}}))
        if chaos is not None:
            config = with_chaos(config, chaos)
        run_dir, failures, notes = launch(config, out, show_progress=not quiet, stop=stop_on_signals(), restart=restart)
    except SwarmlocError as exc:
        _fail(str(exc))
    _print_result(run_dir, failures, notes)


def with_chaos(config, seed: int):
    """``config`` with a chaos fault timeline (every kind of fault) added to its own faults."""
    from bus.config import build_config
    from groundstation.chaos import chaos_faults

    data = config.model_dump(mode="json")
    data["faults"] = data["faults"] + chaos_faults(seed, vehicles=config.world.vehicles, duration_s=config.clock.duration_s,
                                                   spacing_m=config.world.spacing_m)
    return build_config(data)


def _print_result(run_dir: Path, failures: list[str], notes: list[str]) -> None:
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
    report_ok = _report(run_dir, console)
    if failures or not summary_path.exists() or not report_ok:
        raise typer.Exit(1)


def _report(run_dir: Path, console) -> bool:
    """Write the report of ``run_dir`` and say where it is; a failure is one line, never a traceback."""
    from groundstation.report import ReportError, write_report

    try:
        result = write_report(run_dir)
    except ReportError as exc:
        console.print(f"[red]swarm: error: {exc}[/red]", highlight=False)
        return False
    except Exception as exc:  # the run itself is safe on disk; say what went wrong and go on
        console.print(f"[red]swarm: report of {run_dir} failed: {type(exc).__name__}: {exc}[/red]")
        return False
    for problem in result.problems:
        console.print(f"[yellow]report: {problem}[/yellow]")
    console.print(f"report: {result.html}")
    return True


@app.command()
def report(run_dir: Path = typer.Argument(..., help="a run directory written by `swarm up` (may be partial)")) -> None:
    """Write report.html (self-contained) and report/*.png for a run directory; says what is missing."""
    from rich.console import Console

    if not _report(run_dir, Console()):
        raise typer.Exit(1)


@app.command()
def router(listen: list[str] = typer.Option(["tcp/0.0.0.0:7447"], help="zenoh endpoint(s) to listen on")) -> None:
    """Run a zenoh router (what vehicles, world and ground station connect to)."""
    from bus.process import stop_on_signals
    from groundstation.router import run_router

    run_router(tuple(listen), stop_on_signals())


@app.command()
def sim(config: Path = typer.Option(..., help="swarm config JSON")) -> None:
    """Run the world process: truth, sensor feeds and the clock."""
    from sim.node import run_world

    _run_node(config, "world", run_world)


@app.command()
def vehicle(config: Path = typer.Option(..., help="swarm config JSON"),
            id: int = typer.Option(..., "--id", min=1, max=250, help="vehicle id (MAVLink sysid)"),
            restarts: int = typer.Option(0, min=0, max=255, help="how often this vehicle was started before (reset_counter)")) -> None:
    """Run one vehicle process: the fixed-rate estimator loop."""
    from vehicle.loops import run_vehicle

    _run_node(config, "vehicle", lambda bus, cfg, stop: run_vehicle(bus, cfg, id, stop, restarts=restarts))


@app.command()
def gs(config: Path = typer.Option(..., help="swarm config JSON"),
       run_dir: Path = typer.Option(..., help="run directory to write (appended if it exists)"),
       quiet: bool = typer.Option(False, help="no live display")) -> None:
    """Run the ground station: score estimates against truth and write the run directory."""
    from groundstation.display import live_display
    from groundstation.node import run_groundstation

    def body(bus, cfg, stop) -> None:
        with live_display(cfg.clock.mode, cfg.clock.duration_s, quiet) as on_progress:
            run_groundstation(bus, cfg, run_dir, stop, on_progress)

    _run_node(config, "groundstation", body)


if __name__ == "__main__":
    app()
