"""The report's figures, drawn with matplotlib's object API (no pyplot state, no display needed).

Each function takes the loaded run and returns a Figure, or None when the run has nothing to draw.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle
from matplotlib.ticker import FormatStrFormatter

from bus.consistency import BLOCK_S, consistency
from bus.statistics import binned_mean, binned_rms
from groundstation.report.panels import mark_events, marker_legend, panels_legend, worst_vehicles
from groundstation.report.rundata import RunData
from groundstation.report.stats import binned_nees, covariance_ellipse
from groundstation.scene_primitives import zone_colour
from groundstation.shown import SHOWN


def _color(index: int) -> Any:
    return f"C{index % 10}"


def map_figure(data: RunData, *, ellipse_every_s: float = 5.0) -> Figure | None:
    """Top-down map: true (solid) and estimated (dashed) tracks, 3-sigma position ellipses every
    ``ellipse_every_s`` seconds, and jamming/spoofing zones announced in the events."""
    if not data.est and not data.truth:
        return None
    fig = Figure(figsize=(8.0, 7.0), layout="constrained")
    ax = fig.subplots()
    for i, vid in enumerate(data.vehicles):
        if vid in data.truth:
            ax.plot(data.truth[vid][:, 1], data.truth[vid][:, 2], "-", color=_color(i), lw=1.0, alpha=0.6)
        if vid in data.est:
            ax.plot(data.est[vid][:, 1], data.est[vid][:, 2], "--", color=_color(i), lw=1.0, label=f"v{vid}")
            _draw_ellipses(ax, data, vid, _color(i), ellipse_every_s)
    for i, vid in enumerate(data.vehicles):
        if vid in data.maps:
            _draw_landmarks(ax, *data.maps[vid], _color(i), vid)
    for zone in data.zones():
        ax.add_patch(
            Circle(
                tuple(zone["center_m"]),
                zone["radius_m"],
                color=zone_colour(str(zone.get("fault"))),
                alpha=0.15,
                lw=1.5,
                label=f"{zone['fault']} {zone['name']}".strip(),
            )
        )
    _frame_on_tracks(ax, data)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    landmarks = "; landmarks (+) with 3-sigma ellipses" if data.maps else ""
    ax.set_title(
        f"tracks: true solid, estimated dashed; 3-sigma ellipses every {ellipse_every_s:g} s{landmarks}",
        fontsize="medium",
    )
    ax.grid(alpha=0.3)
    _map_legend(ax, len(data.vehicles))
    return fig


def _map_legend(ax: Any, vehicles: int) -> None:
    """Every track and zone; beyond ``SHOWN`` vehicles the zones alone (a legend of hundreds
    of vehicles would hide the map)."""
    if vehicles <= SHOWN:
        ax.legend(loc="upper right", fontsize="small", ncols=2)
        return
    zones = [(h, label) for h, label in zip(*ax.get_legend_handles_labels()) if not label.startswith("v")]
    if zones:
        ax.legend(*zip(*zones), loc="upper right", fontsize="small")


def _frame_on_tracks(ax: Any, data: RunData, margin: float = 0.15) -> None:
    """Equal axes around the tracks and maps (a zone larger than the flight would shrink them to dots)."""
    points = [rows[:, 1:3] for rows in (*data.est.values(), *data.truth.values())] + [
        xy for xy, _ in data.maps.values()
    ]
    points = [p for p in points if len(p)]
    if points:
        allp = np.vstack(points)
        low, high = allp.min(axis=0), allp.max(axis=0)
        pad = margin * max(float(np.max(high - low)), 1.0)
        ax.set_xlim(low[0] - pad, high[0] + pad)
        ax.set_ylim(low[1] - pad, high[1] + pad)
    ax.set_aspect("equal", adjustable="box")


def _draw_landmarks(ax: Any, xy: np.ndarray, cov: np.ndarray, color: Any, vid: int) -> None:
    """A SLAM vehicle's map: landmarks (+) and their 3-sigma ellipses (vision EKF-SLAM paper, figs. 4-5)."""
    ax.plot(xy[:, 0], xy[:, 1], "+", color=color, ms=3, mew=0.6, label=f"v{vid} map ({len(xy)} landmarks)")
    for centre, c in zip(xy, cov):
        outline = centre + covariance_ellipse(c, points=24)
        ax.plot(outline[:, 0], outline[:, 1], "-", color=color, lw=0.3, alpha=0.5)


def _draw_ellipses(ax: Any, data: RunData, vid: int, color: Any, every_s: float) -> None:
    rows = data.rows_of(vid)
    if not rows:
        return
    t = rows["t_s"]
    picks = np.unique(np.searchsorted(t, np.arange(t[0], t[-1] + 1e-9, every_s)).clip(0, len(t) - 1))
    est = data.est[vid]
    cov_xy = rows.get("cov_xy_m2", np.zeros_like(t))
    for k in picks:
        center = np.array([np.interp(t[k], est[:, 0], est[:, 1]), np.interp(t[k], est[:, 0], est[:, 2])])
        cov = np.array([[rows["sigma_x_m"][k] ** 2, cov_xy[k]], [cov_xy[k], rows["sigma_y_m"][k] ** 2]])
        outline = center + covariance_ellipse(cov)
        ax.plot(outline[:, 0], outline[:, 1], "-", color=color, lw=0.7)


def _rmse_of(rows: dict[str, np.ndarray]) -> float:
    return float(np.sqrt(np.mean(np.square(rows["err_pos_m"]))))


def _inconsistency_of(rows: dict[str, np.ndarray]) -> float:
    """How far a vehicle's mean NEES is from 3, either way (a factor: log scale)."""
    mean = float(np.nanmean(rows["nees"]))
    return abs(np.log(mean / 3.0)) if mean > 0 else np.inf


def error_figure(data: RunData) -> Figure | None:
    """Position error per axis over time per vehicle, inside its shaded 3-sigma envelope (the vehicles
    with the largest RMSE when there are more than ``SHOWN``)."""
    vehicles, total = worst_vehicles(data, _rmse_of)
    series = [
        (f"err_{axis}_m", f"sigma_{axis}_m", color, f"{axis} error") for axis, color in (("x", "C0"), ("y", "C1"))
    ]
    title = "position error per axis (lines) and its 3-sigma envelope (shaded)"
    return _envelope_figure(data, vehicles, total, series, title, "with the largest RMSE")


def _height_rmse_of(rows: dict[str, np.ndarray]) -> float:
    errors = rows.get("err_alt_m", np.zeros(0))
    return float(np.sqrt(np.nanmean(np.square(errors)))) if np.isfinite(errors).any() else -1.0


def height_figure(data: RunData) -> Figure | None:
    """The height error over time of each vehicle that estimates its height (a UAV), inside its shaded
    3-sigma envelope (the vehicles with the largest height RMSE when there are more than ``SHOWN``);
    None when no vehicle does."""
    vehicles, _ = worst_vehicles(data, _height_rmse_of)
    vehicles = [v for v in vehicles if _height_rmse_of(data.rows_of(v)) >= 0.0]
    total = sum(_height_rmse_of(data.rows_of(v)) >= 0.0 for v in data.vehicles)
    series = [("err_alt_m", "sigma_alt_m", "C2", "height error")]
    title = "height error above the launch point (line) and its 3-sigma envelope (shaded)"
    return _envelope_figure(data, vehicles, total, series, title, "with the largest height RMSE")


def _envelope_figure(
    data: RunData, vehicles: list[int], total: int, series: list[tuple[str, str, str, str]], title: str, which: str
) -> Figure | None:
    """A panel per vehicle of ``vehicles`` (of ``total``): each of ``series`` (error column, sigma
    column, colour, label) over time inside its shaded 3-sigma envelope, with the fault markers; None
    without vehicles."""
    if not vehicles:
        return None
    fig = Figure(figsize=(9.0, 1.0 + 1.7 * len(vehicles)), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(vehicles), 1, sharex=True))
    events = data.marker_events()
    for ax, vid in zip(axes, vehicles):
        r = data.rows_of(vid)
        for error, sigma, color, label in series:
            bound = 3.0 * r[sigma]
            ax.fill_between(r["t_s"], -bound, bound, color=color, alpha=0.15, lw=0)
            ax.plot(r["t_s"], r[error], color=color, lw=0.8, label=label)
        mark_events(ax, events, vid)
        ax.set_ylabel(f"v{vid} [m]")
        ax.grid(alpha=0.3)
    axes[0].set_title(title)
    marker_legend(axes[0], events)
    panels_legend(fig, axes[0], len(vehicles), total, which)
    axes[-1].set_xlabel("sim time [s]")
    return fig


def rmse_figure(data: RunData, *, bin_s: float = 1.0) -> Figure | None:
    """Swarm RMSE per ``bin_s`` seconds (bold) over the per-vehicle RMSE (thin; beyond
    ``SHOWN`` vehicles their median and 5-95 % band instead), with fault markers."""
    m = data.metrics
    if not m or not len(m["t_s"]):
        return None
    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    ax = fig.subplots()
    per_vehicle = [binned_rms(r["t_s"], r["err_pos_m"], bin_s) for r in map(data.rows_of, data.vehicles) if r]
    if len(per_vehicle) <= SHOWN:
        for i, (t, rms) in enumerate(per_vehicle):
            ax.plot(t, rms, color=_color(i), lw=0.6, alpha=0.6)
        what = "thin: each vehicle"
    else:
        t, low, median, high = _spread(per_vehicle)
        ax.fill_between(t, low, high, color="tab:blue", alpha=0.25, lw=0, label="5-95 % of the vehicles")
        ax.plot(t, median, color="tab:blue", lw=1.0, label="median vehicle")
        what = f"{len(per_vehicle)} vehicles: their median and 5-95 % band"
    ax.plot(*binned_rms(m["t_s"], m["err_pos_m"], bin_s), color="black", lw=2.0, label="swarm")
    events = data.marker_events()
    mark_events(ax, events)
    marker_legend(ax, events)
    ax.set_xlabel("sim time [s]")
    ax.set_ylabel(f"RMSE per {bin_s:g} s [m]")
    ax.set_ylim(bottom=0.0)
    ax.set_title(f"swarm position RMSE over time ({what})")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize="small")
    return fig


def _spread(series: list[tuple[np.ndarray, np.ndarray]]) -> tuple[np.ndarray, ...]:
    """(bin centres (B,), 5th percentile, median, 95th percentile (B,) each) over the vehicles of
    per-vehicle series (centres, values) that share bins (a vehicle without a bin is left out of it)."""
    centres = np.unique(np.concatenate([t for t, _ in series]))
    table = np.full((len(series), len(centres)), np.nan)
    for row, (t, values) in zip(table, series):
        row[np.searchsorted(centres, t)] = values
    low, median, high = np.nanpercentile(table, [5.0, 50.0, 95.0], axis=0)
    return centres, low, median, high


def nees_figure(data: RunData, *, bin_s: float = 1.0) -> Figure | None:
    """Swarm-average pose NEES per ``bin_s`` seconds against its 95% chi-square band (3 dof)."""
    m = data.metrics
    if not m or not len(m["t_s"]):
        return None
    t, mean, lower, upper = binned_nees(m["t_s"], m["vehicle"], m["nees"], bin_s)
    fig = Figure(figsize=(9.0, 3.6), layout="constrained")
    ax = fig.subplots()
    ax.fill_between(t, lower, upper, color="tab:green", alpha=0.2, lw=0, label="95% chi-square band")
    ax.axhline(3.0, color="tab:green", lw=0.8)
    ax.plot(t, mean, color="black", lw=1.2, marker=".", label="mean over vehicles, one sample each per bin")
    mark_events(ax, data.marker_events())
    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.yaxis.set_minor_formatter(FormatStrFormatter("%g"))
    ax.set_xlabel("sim time [s]")
    ax.set_ylabel("NEES [x, y, yaw]")
    inside = float(np.mean((mean >= lower) & (mean <= upper)))
    ax.set_title(
        f"swarm-average NEES per {bin_s:g} s: {100 * inside:.0f} % of the bins inside the band "
        "(consistent: 95 %, around 3)"
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="upper right", fontsize="small")
    return fig


def block_nees_figure(data: RunData, *, block_s: float = BLOCK_S) -> Figure | None:
    """Per vehicle: its NEES per second (thin), each ``block_s`` block's mean (steps), the block ANEES
    (their mean, red) and its band (shaded; bus.consistency): a consistent filter's steps scatter
    around 3 and their mean falls inside the band."""
    vehicles, total = worst_vehicles(data, _inconsistency_of)
    if not vehicles:
        return None
    fig = Figure(figsize=(9.0, 1.0 + 1.7 * len(vehicles)), layout="constrained")
    axes = np.atleast_1d(fig.subplots(len(vehicles), 1, sharex=True))
    for ax, vid in zip(axes, vehicles):
        r = data.rows_of(vid)
        t, nees = r["t_s"], r["nees"]
        result = consistency(t, nees, block_s=block_s)
        seconds, per_second = binned_mean(t, nees, 1.0)
        centres, per_block = binned_mean(t, nees, block_s)
        ax.plot(seconds, per_second, color="0.6", lw=0.6, label="NEES, mean per second")
        ax.step(centres, per_block, where="mid", color="black", lw=1.4, label=f"mean per {block_s:g} s block")
        if result.blocks:
            ax.axhspan(*result.band, color="tab:green", alpha=0.2, lw=0, label="95 % band of the block ANEES")
            ax.axhline(result.block_anees, color="tab:red", lw=1.2, label="block ANEES (mean of the steps)")
            verdict = "inside" if result.inside else "outside"
            ax.set_title(
                f"v{vid}: block ANEES {result.block_anees:.2f} ({verdict} [{result.band[0]:.2f}, "
                f"{result.band[1]:.2f}]), {100 * result.share_above:.0f} % of NEES above the 95 % point",
                fontsize="small",
                loc="left",
            )
        ax.axhline(3.0, color="tab:green", lw=0.8)
        ax.set_yscale("log")
        ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
        ax.set_ylabel(f"v{vid} NEES")
        ax.grid(alpha=0.3, which="both")
    panels_legend(fig, axes[0], len(vehicles), total, "whose mean NEES is farthest from 3")
    axes[-1].set_xlabel("sim time [s]")
    return fig
