"""What the report's figures share: the fault markers on a time axis and their legend, which
vehicles a figure of per-vehicle panels shows (the worst ``SHOWN`` by a score), and the legend above
such panels. Drawn with matplotlib's object API."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from groundstation.report.rundata import RunData
from groundstation.shown import SHOWN

MARKER_COLORS = {
    "fault_added": "tab:red",
    "fault_removed": "tab:green",
    "fault_expired": "tab:green",
    "vehicle_lost": "black",
    "vehicle_restarted": "tab:purple",
    "estimator_reset": "tab:purple",
    "gnss_unhealthy": "tab:orange",
    "gnss_healthy": "tab:olive",
}


def mark_events(ax: Any, events: list[dict[str, Any]], vehicle: int | None = None) -> None:
    """Vertical lines at fault events; per-vehicle panels show swarm-wide events and their own."""
    for e in events:
        if vehicle is not None and e.get("vehicle") not in (None, vehicle):
            continue
        kind = str(e.get("event"))
        ax.axvline(float(e.get("t_s", 0.0)), color=MARKER_COLORS.get(kind, "tab:gray"), ls=":", lw=1.2)


def marker_legend(ax: Any, events: list[dict[str, Any]]) -> None:
    for kind in sorted({str(e.get("event")) for e in events}):
        ax.plot([], [], ":", color=MARKER_COLORS.get(kind, "tab:gray"), label=kind)


def worst_vehicles(data: RunData, score: Callable[[dict[str, np.ndarray]], float]) -> tuple[list[int], int]:
    """(the vehicles with rows, in order, or the ``SHOWN`` of them with the highest
    ``score`` of their rows when there are more; how many have rows)."""
    vehicles = [v for v in data.vehicles if len(data.rows_of(v).get("t_s", ()))]
    if len(vehicles) <= SHOWN:
        return vehicles, len(vehicles)
    worst = sorted(vehicles, key=lambda v: -score(data.rows_of(v)))[:SHOWN]
    return worst, len(vehicles)


def panels_legend(fig: Figure, first: Any, shown: int, total: int, which: str) -> None:
    """The legend of a figure of per-vehicle panels, above them; titled with which vehicles they are
    when not all."""
    title = f"the {shown} of {total} vehicles {which}" if shown < total else None
    handles, labels = first.get_legend_handles_labels()
    fig.legend(
        handles, labels, loc="outside upper center", fontsize="small", ncols=4, title=title, title_fontsize="small"
    )
