"""A run's row of a campaign's results table: who flew it where and how it ended, and what it measured
(from its summary.json, and the experiment's own measures). Pure, on a finished run directory."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from launch.runspec import RunSpec, measured

ROW_FILE = "row.json"  # in the run directory once the run is done: what resuming a campaign reads


def run_row(
    spec: RunSpec,
    run_dir: Path,
    *,
    campaign: str,
    status: str,
    exit_reason: str,
    worker: str,
    start: str,
    wall_s: float,
) -> dict[str, Any]:
    """The row of one finished (or failed) run. Columns: campaign, run, variant, overrides (JSON), seed,
    worker, start, wall_s, status, exit_reason, vehicles, rmse_m, anees, nees_in_band, per-vehicle
    RMSE (a list, vehicle order), each event kind's count (``events_<kind>``) and the experiment's
    measures (``<name>``, numbers)."""
    row: dict[str, Any] = {
        "campaign": campaign,
        "run": spec.name,
        "variant": spec.variant,
        "overrides": json.dumps(spec.overrides, sort_keys=True),
        "seed": spec.seed,
        "worker": worker,
        "start": start,
        "wall_s": round(wall_s, 3),
        "status": status,
        "exit_reason": exit_reason,
    }
    summary = _summary(run_dir)
    vehicles = summary.get("vehicles") or {}
    ids = sorted(vehicles, key=int)
    swarm = summary.get("swarm") or {}
    samples = [vehicles[v].get("samples", 0) for v in ids]
    inside = [vehicles[v].get("nees_inside_95", math.nan) * vehicles[v].get("samples", 0) for v in ids]
    row |= {
        "vehicles": len(ids),
        "rmse_m": swarm.get("rmse_m"),
        "anees": swarm.get("anees"),
        "nees_in_band": round(sum(inside) / sum(samples), 6) if sum(samples) else None,
        "rmse_per_vehicle_m": [vehicles[v].get("rmse_m") for v in ids],
        **{f"events_{kind}": count for kind, count in sorted((summary.get("events") or {}).items())},
    }
    if status == "complete":
        for key, value in measured(spec, run_dir).items():
            row[key] = value
    return row


def _summary(run_dir: Path) -> dict[str, Any]:
    try:
        data = json.loads((run_dir / "summary.json").read_text())
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}
