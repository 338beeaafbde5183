"""The figures of `swarm experiment ar-slam` (experiments.ar_slam): the AR-EKF-SLAM paper's figures 7
(time per frame) and 8 (squared x error), and the state's size with the pose NEES, over the flight."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bus import statistics
from experiments.ar_slam_track import Track

COMPARED = ("ekf-slam", "fixed 25 m", "ar-ekf-slam", "ar-ekf-slam visual odometry")


def frame_time_figure(tracks: dict[str, Track], names: tuple[str, ...] = COMPARED) -> Figure:
    """The paper's figure 7: time per frame along the flight (a 2 s running median)."""
    return _lines(
        tracks,
        names,
        lambda track: (np.arange(len(track.frame_ms)), _running_median(np.array(track.frame_ms), width=20)),
        xlabel="camera frame",
        ylabel="estimator time per frame [ms] (running median)",
        title="Cost per frame",
    )


def x_error_figure(tracks: dict[str, Track], names: tuple[str, ...] = COMPARED) -> Figure:
    """The paper's figure 8: squared x error over time."""
    return _lines(
        tracks,
        names,
        lambda track: (track.t_s, track.x_error_m2),
        xlabel="time [s]",
        ylabel="(x - x_hat)^2 [m^2]",
        title="Squared x error",
    )


def _lines(tracks: dict[str, Track], names: tuple[str, ...], series: Callable, **labels: str) -> Figure:
    """One axis, a line per named track: ``series(track)`` gives its (x, y)."""
    fig = Figure(figsize=(8, 4))
    ax = fig.add_subplot()
    for name in names:
        if name in tracks:
            ax.plot(*series(tracks[name]), label=name)
    ax.set(**labels)
    ax.legend()
    ax.grid(alpha=0.3)
    return fig


def _running_median(values: np.ndarray, *, width: int) -> list[float]:
    """The median of each value and the ``width`` before it."""
    return [np.median(values[max(0, k - width) : k + 1]) for k in range(len(values))]


def state_figure(tracks: dict[str, Track], names: tuple[str, ...] = COMPARED) -> Figure:
    """State dimension and pose NEES over time."""
    fig = Figure(figsize=(8, 6))
    top, bottom = fig.subplots(2, 1, sharex=True)
    for name in names:
        if name in tracks:
            top.plot(tracks[name].t_s, tracks[name].state_dim, label=name)
            bottom.plot(tracks[name].t_s, tracks[name].nees, label=name, lw=0.8)
    low, high = statistics.chi2_band(statistics.POSE_NEES_DOF, runs=1)
    bottom.axhspan(low, high, color="green", alpha=0.1, label="95 % band")
    top.set(ylabel="state dimension", title="State size and pose NEES")
    bottom.set(xlabel="time [s]", ylabel="pose NEES (3 dof)", yscale="log")
    top.legend()
    bottom.legend()
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
    return fig


def write_figures(folder: Path, tracks: dict[str, Track]) -> list[Path]:
    """The three figures, as PNG files in ``folder``."""
    paths = []
    for name, figure in (
        ("frame_time.png", frame_time_figure(tracks)),
        ("x_error.png", x_error_figure(tracks)),
        ("state_and_nees.png", state_figure(tracks)),
    ):
        path = folder / name
        figure.savefig(path, dpi=110, bbox_inches="tight")
        paths.append(path)
    return paths
