"""The figures of `swarm experiment cooperative` (experiments.cooperative): the jammed vehicles'
position RMSE and pose ANEES over the jam, one line per variant."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from bus import statistics


def _binned(
    tracks: dict[int, dict[int, dict[str, np.ndarray]]], key: str, bin_s: float, root_mean_square: bool
) -> tuple[np.ndarray, np.ndarray]:
    """Bin centres (s) and the mean (or RMS) of ``key`` over all seeds and jammed vehicles per bin."""
    t = np.concatenate([v["t_s"] for s in tracks.values() for v in s.values()])
    values = np.concatenate([v[key] for s in tracks.values() for v in s.values()])
    return (statistics.binned_rms if root_mean_square else statistics.binned_mean)(t, values, bin_s)


@dataclass(frozen=True)
class VariantLines:
    """The experiment's figures: one binned line per variant (``labels``), the ``reference`` dashed and
    the ``emphasised`` ones thicker, titled with the ``world`` and where the ``jam`` was."""

    labels: dict[str, str]
    reference: str
    emphasised: tuple[str, ...]
    world: str
    jam: str
    bin_s: float = 2.0

    def lines(self, tracks: dict[str, dict], key: str, root_mean_square: bool) -> tuple[Figure, Any]:
        """A figure with one binned line of ``key`` per variant, log y."""
        fig = Figure(figsize=(9.0, 4.5), layout="constrained")
        ax = fig.subplots()
        for k, (name, by_seed) in enumerate(tracks.items()):
            t, value = _binned(by_seed, key, self.bin_s, root_mean_square)
            ax.plot(
                t,
                value,
                color=f"C{k}",
                lw=1.4 if name in self.emphasised else 1.0,
                ls="--" if name == self.reference else "-",
                label=self.labels.get(name, name),
            )
        ax.set_yscale("log")
        ax.set_xlabel("sim time [s]")
        ax.grid(alpha=0.3, which="both")
        return fig, ax

    def error_figure(self, tracks: dict[str, dict]) -> Figure:
        """Position RMSE of the jammed vehicles over the jam, one line per variant (log scale)."""
        fig, ax = self.lines(tracks, "error_m", True)
        ax.set_ylabel("position RMSE of the jammed vehicles [m]")
        ax.set_title(
            f"{self.jam} ({self.world} world; RMS over seeds and jammed vehicles per {self.bin_s:g} s)",
            fontsize="medium",
        )
        ax.legend(fontsize="small", ncols=2)
        return fig

    def nees_figure(self, tracks: dict[str, dict]) -> Figure:
        """Pose ANEES of the jammed vehicles over the jam per variant, with the 3-dof expectation and
        the chi-square band for the largest variant's count of jammed runs taken as independent."""
        fig, ax = self.lines(tracks, "nees", False)
        runs = max(sum(len(s) for s in by_seed.values()) for by_seed in tracks.values())
        lo, hi = statistics.chi2_band(statistics.POSE_NEES_DOF, runs=runs)
        ax.axhspan(lo, hi, color="grey", alpha=0.2, lw=0, label=f"95% band, {runs} independent runs")
        ax.axhline(statistics.POSE_NEES_DOF, color="black", lw=0.8, ls=":")
        ax.set_ylabel("pose ANEES (3 dof) of the jammed vehicles")
        ax.set_title(
            f"consistency during the jam ({self.world} world; mean over seeds and jammed vehicles per "
            f"{self.bin_s:g} s)",
            fontsize="medium",
        )
        ax.legend(fontsize="small", ncols=2, loc="upper left", framealpha=0.9)
        return fig
