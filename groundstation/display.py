"""What the ground station shows while a run goes: a progress bar (lockstep) or a live table (realtime),
and the final RMSE/NEES table."""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.live import Live
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from bus.consistency import NIS_KINDS
from groundstation.shown import SHOWN


def vehicle_rows(vehicles: dict[str, dict[str, Any]], badness: Any, what: str) -> tuple[list[str], str | None]:
    """(the vehicle ids a table shows, in numeric order, or, beyond ``SHOWN``, the ``SHOWN``
    worst by ``badness(vehicle summary)`` worst first; a caption saying which when not all)."""
    ids = sorted(vehicles, key=lambda vid: (len(vid), vid))
    if len(ids) <= SHOWN:
        return ids, None
    worst = sorted(ids, key=lambda vid: -badness(vehicles[vid]))[:SHOWN]
    return worst, f"the {SHOWN} of {len(ids)} vehicles {what}; every vehicle in summary.json and report.html"


LEAST_CONSISTENT = "least consistent (block ANEES farthest outside its band, then from 3)"


def _rmse(v: dict[str, Any]) -> float:
    value = v.get("rmse_m")
    return math.inf if value is None or not math.isfinite(value) else float(value)


def _inconsistency(v: dict[str, Any]) -> float:
    """How far a vehicle's block ANEES is outside its band (0 inside; vehicles without one last)."""
    c = v.get("consistency") or {}
    anees, band = c.get("block_anees"), c.get("band_95")
    if anees is None or not band or anees <= 0:
        return -1.0
    return max(math.log(band[0] / anees), math.log(anees / band[1]), 0.0) + abs(math.log(anees / 3.0)) * 1e-3


def rmse_table(summary: dict[str, Any], timing: dict[str, Any] | None = None, title: str = "swarm RMSE") -> Table:
    """Per-vehicle and swarm position RMSE, ANEES and loop counters from a summary (and timing)."""
    table = Table(title=title)
    for column in (
        "vehicle",
        "RMSE [m]",
        "max err [m]",
        "ANEES (3 dof)",
        "NEES in 95%",
        "GNSS rejected",
        "overruns",
        "jitter p99 [us]",
    ):
        table.add_column(column, justify="right")
    shown, caption = vehicle_rows(summary["vehicles"], _rmse, "with the largest RMSE")
    for vid in shown:
        v = summary["vehicles"][vid]
        t = (timing or {}).get("vehicles", {}).get(vid, {})
        table.add_row(
            vid,
            _num(v.get("rmse_m")),
            _num(v.get("max_error_m")),
            _num(v.get("anees")),
            _pct(v.get("nees_inside_95")),
            str(v.get("gnss_rejected", "-")),
            str(t.get("overruns", v.get("overruns", "-"))),
            _num(t.get("jitter_p99_us"), 0),
        )
    s = summary["swarm"]
    table.add_row("swarm", _num(s.get("rmse_m")), "", _num(s.get("anees")), "", "", "", "", style="bold")
    table.caption = caption
    return table


def consistency_table(summary: dict[str, Any], title: str = "consistency (NEES)") -> Table:
    """Per vehicle: block ANEES against its band and the NEES tail shares (bus.consistency), from a
    summary whose vehicles carry ``consistency``."""
    table = Table(title=title)
    for column in ("vehicle", "blocks", "block ANEES", "95% band", "inside", "> 95% pt", "< 5% pt"):
        table.add_column(column, justify="right")
    with_blocks = {vid: v for vid, v in summary["vehicles"].items() if v.get("consistency")}
    shown, caption = vehicle_rows(with_blocks, _inconsistency, LEAST_CONSISTENT)
    for vid in shown:
        c = with_blocks[vid]["consistency"]
        band = c.get("band_95") or [None, None]
        table.add_row(
            vid,
            str(c.get("blocks", "-")),
            _num(c.get("block_anees"), 2),
            f"{_num(band[0], 2)}-{_num(band[1], 2)}",
            "yes" if c.get("inside") else "no",
            _pct(c.get("share_above_95")),
            _pct(c.get("share_below_05")),
        )
    inside = sum(bool(v["consistency"].get("inside")) for v in with_blocks.values())
    table.caption = "NEES in 30 s blocks; consistent: inside the band, 5 % above the 95 % point, 5 % below the 5 %" + (
        f"\n{inside} of {len(with_blocks)} vehicles inside; {caption}" if caption else ""
    )
    return table


def altitude_table(summary: dict[str, Any], title: str = "height above the launch point") -> Table | None:
    """Per vehicle that estimates its height (a UAV over relief): its RMSE, largest error, ANEES
    (1 dof) and block ANEES against its band, from a summary whose vehicles carry ``altitude``; None
    when none does."""
    with_height = {vid: v["altitude"] for vid, v in summary["vehicles"].items() if v.get("altitude")}
    if not with_height:
        return None
    table = Table(title=title)
    for column in ("vehicle", "RMSE [m]", "max err [m]", "ANEES (1 dof)", "block ANEES", "95% band", "inside"):
        table.add_column(column, justify="right")
    shown, caption = vehicle_rows(with_height, _rmse, "with the largest RMSE")
    for vid in shown:
        a = with_height[vid]
        c = a.get("consistency") or {}
        band = c.get("band_95") or [None, None]
        table.add_row(
            vid,
            _num(a.get("rmse_m")),
            _num(a.get("max_error_m")),
            _num(a.get("anees")),
            _num(c.get("block_anees"), 2),
            f"{_num(band[0], 2)}-{_num(band[1], 2)}",
            "yes" if c.get("inside") else "no",
        )
    table.caption = caption
    return table


def nis_table(summary: dict[str, Any], title: str = "consistency (NIS of the fused updates)") -> Table | None:
    """Per vehicle and measurement kind (bus.consistency.NIS_KINDS): mean NIS and the shares above the
    95 % and below the 5 % point; None when no vehicle reported any."""
    kinds = [k for k in NIS_KINDS if any(k in v.get("nis", {}) for v in summary["vehicles"].values())]
    if not kinds:
        return None
    table = Table(title=title, min_width=76)
    for column in ("vehicle", *kinds):
        table.add_column(column, justify="right")
    shown, caption = vehicle_rows(summary["vehicles"], _inconsistency, LEAST_CONSISTENT)
    for vid in shown:
        nis = summary["vehicles"][vid].get("nis", {})
        table.add_row(vid, *(_nis(nis.get(k)) for k in kinds))
    table.caption = "mean (2 for a 2-D measurement) / above 95 % pt / below 5 % pt (5 % each if consistent)" + (
        f"\n{caption}" if caption else ""
    )
    return table


def _nis(entry: dict | None) -> str:
    if not entry:
        return "-"
    return f"{entry['mean']:.2f} / {_pct(entry['share_above_95'])} / {_pct(entry['share_below_05'])}"


def _num(value: float | None, digits: int = 3) -> str:
    return "-" if value is None or (isinstance(value, float) and math.isnan(value)) else f"{value:.{digits}f}"


def _pct(value: float | None) -> str:
    return "-" if value is None else f"{100 * value:.1f}%"


@contextmanager
def live_display(mode: str, duration_s: float, quiet: bool) -> Iterator[Any]:
    """Yields an ``on_progress(gs)`` callback that updates the display at most ~5 times a second."""
    if quiet:
        yield None
        return
    console = Console()
    if mode == "lockstep":
        with Progress(
            TextColumn("sim time"),
            BarColumn(),
            TextColumn("{task.completed:.1f}/{task.total:.0f} s"),
            TimeElapsedColumn(),
            console=console,
            transient=True,
        ) as progress:
            task = progress.add_task("run", total=duration_s)
            yield lambda gs: progress.update(task, completed=gs.sim_time_us * 1e-6)
        return
    with Live(console=console, refresh_per_second=4, transient=True) as live:

        def update(gs: Any) -> None:
            if gs.sim_time_us % 500_000 == 0:
                from groundstation.summary import build_summary, rejected_by_process

                rejected = rejected_by_process(gs.rejections, gs.ended, gs.reports.statuses)
                summary = build_summary(gs.config, gs.scorer, gs.reports.statuses, {}, "running", rejected=rejected)
                live.update(rmse_table(summary, title=f"t = {gs.sim_time_us * 1e-6:.1f} s"))

        yield update


def report_and_say(run_dir: Path, console: Console) -> bool:
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
