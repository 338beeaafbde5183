"""`swarm experiment ...`: the papers' experiments, each a folder of ordinary run directories (with
their reports) plus comparison figures and a JSON table (``groundstation.experiments``)."""

from __future__ import annotations

from pathlib import Path

import typer

from bus.errors import SwarmlocError
from groundstation.cli_errors import fail

experiment_app = typer.Typer(add_completion=False, no_args_is_help=True,
                             help="Experiments from the papers, each a folder of ordinary runs plus comparison figures.")


@experiment_app.command("vision-slam")
def vision_slam(
    out: Path = typer.Option(Path("runs"), help="parent folder of the experiment folder"),
    seed: int = typer.Option(3, help="seed of trajectories, sensor noise and terrain"),
    duration: float = typer.Option(60.0, help="simulated seconds per flight"),
    quiet: bool = typer.Option(False, help="no progress display"),
) -> None:
    """The vision EKF-SLAM paper's experiment: a circle and a figure-8 UAV with GNSS jammed all flight,
    flown with ekf-slam on camera frames and again with dead reckoning on the same seed. Writes both
    runs (each with its report and landmark map), the comparison figures and experiment.json."""
    from rich.console import Console

    from bus.process import stop_on_signals
    from groundstation.display import report_and_say
    from groundstation.experiments import compare, run_vision_slam

    try:
        folder, runs, failures = run_vision_slam(out, seed=seed, duration_s=duration, stop=stop_on_signals(),
                                                 show_progress=not quiet)
    except SwarmlocError as exc:
        fail(str(exc))
    console = Console()
    ok = all(report_and_say(run, console) for run in runs.values())
    table, figures = compare(folder, runs)
    for name, flight in table.items():
        landmarks = {vid: v.get("landmarks") for vid, v in flight["vehicles"].items()}
        console.print(f"{name}: {flight['status']}, swarm RMSE {flight['swarm_rmse_m']} m, ANEES {flight['swarm_anees']}"
                      + (f", landmarks {landmarks}" if any(landmarks.values()) else ""), highlight=False)
    for failure in failures:
        console.print(f"[red]swarm: {failure}[/red]")
    for figure in figures:
        console.print(f"figure: {figure}")
    console.print(f"experiment: {folder}")
    if failures or not ok:
        raise typer.Exit(1)
