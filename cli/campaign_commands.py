"""`swarm campaign GRID.toml` (a user's grid of runs, campaign.grid) and `swarm campaign report DIR`
(mean and 95 % interval per variant, campaign.report): one command, registered on the `swarm` app by
``cli.main``."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from bus.errors import SwarmlocError
from cli.errors import fail


def campaign(
    target: str = typer.Argument(..., help="the campaign's TOML grid (docs: campaigns), or: report"),
    folder: Optional[Path] = typer.Argument(None, help="with report: a campaign's folder"),
    out: Path = typer.Option(Path("runs"), help="parent folder of the campaign's folder (<out>/<name>: resumable)"),
    scheduler: Optional[str] = typer.Option(None, help="a Dask scheduler's address (tcp://HOST:8786)"),
    workers: Optional[int] = typer.Option(
        None, min=1, help="runs at once on the local cluster [default: from the cores]"
    ),
    shared: bool = typer.Option(False, help="with --scheduler: the workers see --out at the same path"),
    timeout: float = typer.Option(1800.0, min=1.0, help="wall-clock seconds a run may take before it is ended"),
    quiet: bool = typer.Option(False, help="no progress lines"),
) -> None:
    """`swarm campaign GRID.toml`: fly every run of a grid (scenarios x variants x seeds) on a Dask cluster
    and write results.parquet; the same command again skips the runs that completed and flies the failed
    and missing ones. `swarm campaign report DIR`: mean +- 95 % confidence interval of every metric per
    variant (seeds as independent samples), printed, and a figure per metric in the folder."""
    from rich.console import Console

    console = Console()
    if target == "report":
        if folder is None or not (folder / "results.parquet").is_file():
            fail(f"{folder} holds no results.parquet (not a campaign folder, or no run finished yet)")
        _print_report(folder, console)
        return
    if folder is not None:
        fail(f"unexpected argument {folder}: give one grid file, or `report DIR`")
    from bus.process import stop_on_signals
    from campaign.grid import load_grid
    from campaign.runner import Campaign, run_campaign

    say = (lambda text: None) if quiet else (lambda text: console.print(text, highlight=False))
    try:
        name, specs, cpu = load_grid(Path(target))
        how = Campaign(scheduler=scheduler, workers=workers, cpu_per_run=cpu, timeout_s=timeout, shared=shared)
        rows = run_campaign(specs, out / name, how, stop=stop_on_signals(), say=say)
    except SwarmlocError as exc:
        fail(str(exc))
    _print_report(out / name, console)
    if any(r.get("status") != "complete" for r in rows) or len(rows) < len(specs):
        raise typer.Exit(1)


def _print_report(folder: Path, console) -> None:
    from rich.table import Table

    from campaign.report import by_variant, figures, numeric_metrics
    from campaign.table import read_table

    rows = read_table(folder)
    metrics = numeric_metrics(rows)
    table = by_variant(rows, metrics)
    shown = Table(title=f"{folder.name}: mean +- 95 % interval over seeds")
    shown.add_column("variant")
    shown.add_column("runs", justify="right")
    for metric in metrics:
        shown.add_column(metric, justify="right")
    for variant, values in table.items():
        n = max(v[2] for v in values.values())
        shown.add_row(variant, str(n), *(_cell(*values[m]) for m in metrics))
    console.print(shown)
    for path in figures(table, folder):
        console.print(f"figure: {path}")
    console.print(f"results: {folder / 'results.parquet'}")


def _cell(mean: float, half: float, n: int) -> str:
    if n == 0:
        return "-"
    return f"{mean:.4g}" if half != half else f"{mean:.4g} +- {half:.2g}"
