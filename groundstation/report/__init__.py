"""`swarm report`: PNG figures and one self-contained HTML page from a run directory."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from groundstation.report.rundata import ReportError, load_run
from groundstation.shown import SHOWN

__all__ = ["Report", "ReportError", "write_report"]


@dataclass(frozen=True)
class Report:
    html: Path
    figures: list[Path]
    problems: list[str]


def write_report(run_dir: Path) -> Report:
    """Render ``run_dir/report/*.png`` and ``run_dir/report.html``; works on partial runs and says what is missing."""
    from groundstation.report import figures as f
    from groundstation.report.page import render_page
    from groundstation.report.stats import vehicle_table

    data = load_run(run_dir)
    out = data.path / "report"
    out.mkdir(exist_ok=True)
    notes = []
    if len(data.vehicles) > SHOWN:
        notes.append(f"the per-vehicle figures show {SHOWN} of {len(data.vehicles)} vehicles, each naming which")
    if not data.zones():
        notes.append("no jamming or spoofing zones in this run")
    if not data.maps:
        notes.append("this run's estimators have no landmarks to draw")
    written: list[tuple[str, Path]] = []
    for title, stem, build, always in (
        ("Map", "map", f.map_figure, True),
        ("Position error", "error", f.error_figure, True),
        ("Height error", "height", f.height_figure, False),  # only where a vehicle estimates its height
        ("Swarm RMSE", "rmse", f.rmse_figure, True),
        ("NEES", "nees", f.nees_figure, True),
        ("NEES per vehicle, in blocks", "nees_blocks", f.block_nees_figure, True),
    ):
        figure = build(data)
        if figure is None:
            notes += [f"{title}: nothing to draw"] if always else []
            continue
        png = out / f"{stem}.png"
        figure.savefig(png, dpi=100)
        written.append((title, png))
    page = data.path / "report.html"
    page.write_text(render_page(data, vehicle_table(data), written, notes), encoding="utf-8")
    return Report(html=page, figures=[p for _, p in written], problems=data.problems)
