"""One self-contained HTML page: figures embedded as base64 PNG, inline CSS, links only to the run's own files."""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

from groundstation.report.rundata import RunData
from groundstation.report.stats import swarm_rmse

STYLE = """body{font-family:system-ui,sans-serif;margin:2em auto;max-width:1000px;color:#222}
table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f0f0f0}.problems{background:#fff4e5;border-left:4px solid #f90;padding:.5em 1em}
img{max-width:100%}code{background:#f4f4f4;padding:0 3px}"""
TABLE_COLUMNS = (
    ("vehicle", "vehicle"),
    ("samples", "samples"),
    ("rmse_m", "RMSE [m]"),
    ("max_error_m", "max error [m]"),
    ("anees", "ANEES (3 dof)"),
    ("resets", "resets"),
    ("overruns", "overruns"),
    ("gnss_rejected", "GNSS rejected"),
    ("dropped_stale", "stale dropped"),
    ("mavlink_rejected", "MAVLink rejected"),
    ("decode_errors", "decode errors"),
)
RAW_FILES = ("summary.json", "metrics.csv", "events.jsonl", "config.json", "timing.json")
MAX_EVENT_ROWS = 300


def _cell(value: Any) -> str:
    if value is None:
        return "-"
    return f"{value:.3f}" if isinstance(value, float) else html.escape(str(value))


def _table(rows: list[dict[str, Any]]) -> str:
    head = "".join(f"<th>{label}</th>" for _, label in TABLE_COLUMNS)
    body = "".join(
        "<tr>" + "".join(f"<td>{_cell(r.get(key))}</td>" for key, _ in TABLE_COLUMNS) + "</tr>" for r in rows
    )
    return f"<table><tr>{head}</tr>{body}</table>"


HEIGHT_COLUMNS = (("rmse_m", "RMSE [m]"), ("max_error_m", "max error [m]"), ("anees", "ANEES (1 dof)"))


def _height_table(summary: dict[str, Any]) -> str:
    """The vehicles that estimate their height (summary.json ``altitude``): its scores, with the block
    ANEES against its band; empty when none does."""
    heights = {vid: v["altitude"] for vid, v in (summary.get("vehicles") or {}).items() if v.get("altitude")}
    if not heights:
        return ""
    head = "<th>vehicle</th>" + "".join(f"<th>{label}</th>" for _, label in HEIGHT_COLUMNS)
    head += "<th>block ANEES</th><th>95% band</th>"
    rows = ""
    for vid in sorted(heights, key=lambda v: (len(v), v)):
        h, c = heights[vid], heights[vid].get("consistency") or {}
        band = c.get("band_95") or [None, None]
        cells = [vid, *(h.get(key) for key, _ in HEIGHT_COLUMNS), c.get("block_anees")]
        rows += "<tr>" + "".join(f"<td>{_cell(v)}</td>" for v in cells)
        rows += f"<td>{_cell(band[0])}-{_cell(band[1])}</td></tr>"
    return f"<h2>Height above the launch point</h2><table><tr>{head}</tr>{rows}</table>"


def _events(events: list[dict[str, Any]]) -> str:
    shown = events[:MAX_EVENT_ROWS]
    rows = "".join(
        f"<tr><td>{_cell(e.get('t_s'))}</td><td style='text-align:left'>{html.escape(str(e.get('event')))}</td>"
        "<td style='text-align:left'><code>"
        + html.escape(str({k: v for k, v in e.items() if k not in ("t_s", "event")}))
        + "</code></td></tr>"
        for e in shown
    )
    more = f"<p>{len(events) - len(shown)} more in events.jsonl</p>" if len(events) > len(shown) else ""
    return f"<table><tr><th>t [s]</th><th>event</th><th>details</th></tr>{rows}</table>{more}"


def _figure(title: str, png: Path) -> str:
    encoded = base64.b64encode(png.read_bytes()).decode("ascii")
    return f"<h2>{html.escape(title)}</h2><img alt='{html.escape(title)}' src='data:image/png;base64,{encoded}'>"


def render_page(
    data: RunData, table_rows: list[dict[str, Any]], figures: list[tuple[str, Path]], notes: list[str]
) -> str:
    """The HTML text of the report; ``figures`` are (title, PNG path) pairs to embed."""
    summary = data.summary or {}
    name = summary.get("name") or (data.config or {}).get("name") or data.path.name
    status = summary.get("status", "unfinished (no summary.json)")
    rmse = swarm_rmse(data)
    problems = "".join(f"<li>{html.escape(p)}</li>" for p in data.problems + notes)
    links = " &middot; ".join(f"<a href='{f}'>{f}</a>" for f in RAW_FILES if (data.path / f).exists())
    parts = [
        f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>swarmloc report: {html.escape(name)}</title>",
        f"<style>{STYLE}</style></head><body>",
        f"<h1>swarmloc run <code>{html.escape(name)}</code></h1>",
        f"<p>status: <b>{html.escape(str(status))}</b> &middot; mode: {html.escape(str(summary.get('mode', '-')))}"
        f" &middot; seed: {html.escape(str(summary.get('seed', '-')))} &middot; vehicles: {len(data.vehicles)}"
        f" &middot; swarm RMSE: <b>{_cell(rmse)} m</b></p>",
        f"<div class='problems'><b>What is missing or was skipped</b><ul>{problems}</ul></div>" if problems else "",
        "<h2>Per vehicle</h2>",
        _table(table_rows),
        _height_table(summary),
        *(_figure(title, png) for title, png in figures),
        "<h2>Events</h2>",
        _events(data.events),
        f"<p>raw files: {links}</p>" if links else "",
        "</body></html>",
    ]
    return "\n".join(parts)
