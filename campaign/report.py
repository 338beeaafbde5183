"""`swarm campaign report DIR`: a campaign's results per variant: mean and 95 % confidence interval of
each metric over its runs (seeds as independent samples: mean +- t(0.975, n-1) s / sqrt(n)), as a
table and one figure per metric (the variants side by side with their intervals). Only completed
runs count."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from bus.statistics import interval

METRICS = (("rmse_m", "swarm RMSE [m]"), ("anees", "ANEES (3 dof)"), ("nees_in_band", "NEES in 95 % band"))


def by_variant(rows: list[dict[str, Any]], metrics: tuple[str, ...]) -> dict[str, dict[str, tuple[float, float, int]]]:
    """{variant: {metric: (mean, half width, n)}} over the completed runs, variants in table order."""
    variants = list(dict.fromkeys(r["variant"] for r in rows))
    done = [r for r in rows if r.get("status") == "complete"]
    return {v: {m: interval([r.get(m) for r in done if r["variant"] == v]) for m in metrics} for v in variants}


def numeric_metrics(rows: list[dict[str, Any]]) -> tuple[str, ...]:
    """METRICS first, then every other numeric column an experiment measured (not bookkeeping)."""
    skip = {"seed", "wall_s", "vehicles"}
    extra = [
        key
        for key in dict.fromkeys(k for r in rows for k in r)
        if key not in skip
        and key not in dict(METRICS)
        and not key.startswith("events_")
        and any(isinstance(r.get(key), (int, float)) and not isinstance(r.get(key), bool) for r in rows)
    ]
    return (*(m for m, _ in METRICS), *extra)


def figures(table: dict[str, dict[str, tuple[float, float, int]]], folder: Path) -> list[Path]:
    """One bar figure per METRICS entry: each variant's mean with its 95 % interval."""
    from matplotlib.figure import Figure

    written = []
    names = list(table)
    for metric, label in METRICS:
        means = [table[v][metric][0] for v in names]
        if not any(math.isfinite(m) for m in means):
            continue
        errors = [0.0 if math.isnan(table[v][metric][1]) else table[v][metric][1] for v in names]
        fig = Figure(figsize=(max(5.0, 0.9 * len(names) + 2.0), 3.8), layout="constrained")
        ax = fig.subplots()
        ax.bar(range(len(names)), means, yerr=errors, capsize=4, color="C0", alpha=0.8)
        ax.set_xticks(range(len(names)), names, rotation=30, ha="right", fontsize="small")
        ax.set_ylabel(label)
        ax.set_title(f"{label}: mean and 95 % interval over seeds", fontsize="medium")
        ax.grid(axis="y", alpha=0.3)
        path = folder / f"campaign_{metric}.png"
        fig.savefig(path, dpi=100)
        written.append(path)
    return written
