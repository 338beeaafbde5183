"""What a command that ran a swarm prints: its notes and failures, its table, its report."""

from __future__ import annotations

import json
from pathlib import Path

import typer


def print_result(
    run_dir: Path, failures: list[str], notes: list[str], *, report: bool = True, consistency: bool = False
) -> None:
    """The run's table (``consistency``: and its consistency table), then its report (``report``:
    written now; else how to write it later); exits 1 when a process failed, no summary was written or
    the report could not be."""
    from rich.console import Console

    from groundstation.display import altitude_table, consistency_table, nis_table, rmse_table

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
        heights = altitude_table(summary)
        if heights is not None:
            console.print(heights)
        if consistency:
            console.print(consistency_table(summary))
            nis = nis_table(summary)
            if nis is not None:
                console.print(nis)
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
