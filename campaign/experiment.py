"""An experiment flown as a campaign: its registered module plans the runs (experiments.registry), the
campaign layer flies them (campaign.runner) into ``<out>/<experiment>``, and the module concludes from
the results table (experiment.json, figures, lines to print). The same command again resumes: the
folder is the experiment's name, not a fresh one."""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from bus.config import ViewConfig
from bus.errors import SwarmlocError
from campaign.runner import Campaign, run_campaign
from experiments.registry import EXPERIMENTS, module_of
from launch.runspec import RunSpec


def run_experiment(
    name: str,
    params: dict[str, Any],
    out: Path,
    how: Campaign,
    *,
    stop: threading.Event,
    view: ViewConfig | None = None,
    say: Callable[[str], None] = lambda text: None,
) -> tuple[Path, list[dict[str, Any]], list[str]]:
    """Fly the experiment ``name`` with its ``params``; (its folder, the rows, the lines to print). A
    live ``view`` flies the runs one after another (each serves the view in turn, on one port)."""
    module = module_of(name)
    specs = module.plan(**params)
    if view is not None:
        specs = [_with_view(spec, view) for spec in specs]
        how = replace(how, scheduler=None, workers=1)
    how = replace(how, cpu_per_run=EXPERIMENTS[name].cpu_per_run)
    folder = out / name
    rows = run_campaign(specs, folder, how, stop=stop, say=say)
    complete = sum(row.get("status") == "complete" for row in rows)
    if stop.is_set() and len(rows) < len(specs):
        raise SwarmlocError(
            f"experiment {name} stopped with {complete} of {len(specs)} runs complete, nothing concluded: "
            "the same command resumes it"
        )
    if not complete:
        return folder, rows, [f"experiment {name}: none of its {len(specs)} runs completed, nothing concluded"]
    return folder, rows, module.conclude(rows, folder, **params)


def _with_view(spec: RunSpec, view: ViewConfig) -> RunSpec:
    return replace(spec, config={**spec.config, "view": view.model_dump(mode="json")})
