"""Is a filter's covariance honest? Consistency statistics for NEES (or NIS) sequences whose epochs are
strongly autocorrelated, as a filter's errors are: one epoch's NEES tells little that the previous
one did not say.

- **Block ANEES.** The samples are cut into blocks of ``block_s`` seconds, longer than the error's
  correlation time; each block's mean NEES counts as one sample, and the average over the B blocks is
  judged against the chi-square band of B samples of ``dof`` each (Bar-Shalom, Li, Kirubarajan 2001,
  sec. 5.4.2, with blocks for runs). The band of every epoch taken as independent is far too narrow:
  10 Hz over 660 s gives [2.98, 3.02] for 3 dof, 30 s blocks give [2.06, 4.10].
- **Tail shares.** The share of epochs whose NEES is above the upper ``tail`` point of chi-square(dof)
  and the share below its lower one (``tail`` = 5 %: 5 % each for a consistent filter). Autocorrelation
  leaves these expectations unchanged; it only widens their spread.

A block holding fewer than half the samples of the median block (a run's last partial block, a gap in
the truth) is left out: it would count as a whole independent sample. Pure.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass, field
from functools import cache

import numpy as np

from bus.statistics import POSE_NEES_DOF, chi2_band, upper_quantile

BLOCK_S = 30.0  # longer than a filter's error correlation time (MRCLAM's blind stretches, a jam)
TAIL = 0.05  # the share of a consistent filter's NEES above (and below) the tail points


@dataclass(frozen=True)
class Consistency:
    """The consistency of one NEES sequence (see the module docstring)."""

    samples: int
    blocks: int
    block_anees: float  # mean over the blocks of each block's mean NEES (nan without a block)
    band: tuple[float, float]  # the two-sided 95 % band of block_anees for a consistent filter
    share_above: float  # share of samples above the upper TAIL point of chi-square(dof)
    share_below: float  # share below the lower TAIL point

    @property
    def inside(self) -> bool:
        return self.blocks > 0 and self.band[0] <= self.block_anees <= self.band[1]

    def as_dict(self) -> dict:
        return {
            "samples": self.samples,
            "blocks": self.blocks,
            "block_anees": _round(self.block_anees),
            "band_95": [_round(b) for b in self.band],
            "inside": self.inside,
            "share_above_95": _round(self.share_above),
            "share_below_05": _round(self.share_below),
        }


def tail_points(dof: int = POSE_NEES_DOF, tail: float = TAIL) -> tuple[float, float]:
    """(lower, upper) ``tail`` points of chi-square(``dof``): P(X < lower) = P(X > upper) = ``tail``."""
    return upper_quantile(dof, 1.0 - tail), upper_quantile(dof, tail)


def consistency(
    t_s: np.ndarray, nees: np.ndarray, *, dof: int = POSE_NEES_DOF, block_s: float = BLOCK_S
) -> Consistency:
    """The consistency of NEES samples ``nees`` (N,) taken at times ``t_s`` (N,) s."""
    t_s, nees = np.asarray(t_s, dtype=float), np.asarray(nees, dtype=float)
    if t_s.shape != nees.shape or t_s.ndim != 1:
        raise ValueError(f"times {t_s.shape} and NEES {nees.shape} must be two 1-D arrays of one length")
    keep = np.isfinite(t_s) & np.isfinite(nees)
    t_s, nees = t_s[keep], nees[keep]
    _, block = np.unique(np.floor(t_s / block_s), return_inverse=True)
    low, high = tail_points(dof)
    return summarize(
        np.bincount(block, weights=nees),
        np.bincount(block),
        samples=int(nees.size),
        above=int(np.sum(nees > high)),
        below=int(np.sum(nees < low)),
        dof=dof,
    )


def summarize(
    block_sums: np.ndarray, block_counts: np.ndarray, *, samples: int, above: int, below: int, dof: int
) -> Consistency:
    """The verdict from each block's NEES sum (B,) and sample count (B,), and the counts of samples in
    all, above the upper and below the lower TAIL point (blocks under half the median count left out)."""
    sums, counts = np.asarray(block_sums, dtype=float), np.asarray(block_counts, dtype=float)
    full = counts >= 0.5 * np.median(counts) if counts.size else counts.astype(bool)
    means = sums[full] / counts[full]
    blocks = int(means.size)
    band = chi2_band(dof, runs=blocks) if blocks else (float("nan"), float("nan"))
    share = (lambda k: k / samples) if samples else (lambda k: float("nan"))
    return Consistency(
        samples=samples,
        blocks=blocks,
        block_anees=float(means.mean()) if blocks else float("nan"),
        band=(float(band[0]), float(band[1])),
        share_above=share(above),
        share_below=share(below),
    )


@dataclass
class ConsistencyTally:
    """The running totals behind :func:`consistency`, one NEES at a time (the ground station's)."""

    dof: int = POSE_NEES_DOF
    block_s: float = BLOCK_S
    samples: int = 0
    above: int = 0
    below: int = 0
    blocks: dict[int, list] = field(default_factory=lambda: defaultdict(lambda: [0.0, 0]))  # index -> [sum, n]
    points: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        self.points = tail_points(self.dof)

    def add(self, t_s: float, nees: float) -> None:
        if not (math.isfinite(t_s) and math.isfinite(nees)):
            return
        self.samples += 1
        self.above += int(nees > self.points[1])
        self.below += int(nees < self.points[0])
        entry = self.blocks[math.floor(t_s / self.block_s)]
        entry[0] += nees
        entry[1] += 1

    def result(self) -> Consistency:
        entries = [self.blocks[index] for index in sorted(self.blocks)]
        return summarize(
            [total for total, _ in entries],
            [count for _, count in entries],
            samples=self.samples,
            above=self.above,
            below=self.below,
            dof=self.dof,
        )


NIS_KINDS = ("landmark", "robot", "seen", "gnss")  # a vehicle's sightings of landmarks, its own sightings
# of neighbours (fused with their broadcasts), neighbours' sightings of it relayed, and GNSS fixes
NIS_FIELDS = 4  # per kind: count, sum of NIS, count above the upper TAIL point, count below the lower


@dataclass(frozen=True)
class NisBook:
    """A vehicle's running NIS per measurement kind (NIS_KINDS) of the updates it fused: ``values``
    holds per kind (count, sum, above the upper TAIL point, below the lower) of chi-square(dof), dof the
    measurement's dimension. Immutable (a filter state's snapshot shares it); ``add`` returns a new book."""

    values: tuple[float, ...] = (0.0,) * (NIS_FIELDS * len(NIS_KINDS))

    def add(self, kind: str, nis: float, dof: int) -> NisBook:
        if not math.isfinite(nis):
            return self
        low, high = _cached_tail_points(dof)
        k = NIS_FIELDS * NIS_KINDS.index(kind)
        values = list(self.values)
        values[k : k + NIS_FIELDS] = (
            values[k] + 1.0,
            values[k + 1] + nis,
            values[k + 2] + float(nis > high),
            values[k + 3] + float(nis < low),
        )
        return NisBook(tuple(values))


def nis_summary(values: tuple[float, ...]) -> dict[str, dict]:
    """Per measurement kind with any update: count, mean NIS and the shares above the upper and below
    the lower TAIL point, from a NisBook's ``values`` (as a VehicleStatus carries them)."""
    summary: dict[str, dict] = {}
    if len(values) != NIS_FIELDS * len(NIS_KINDS):
        return summary
    for i, kind in enumerate(NIS_KINDS):
        count, total, above, below = values[NIS_FIELDS * i : NIS_FIELDS * (i + 1)]
        if count > 0:
            summary[kind] = {
                "count": int(count),
                "mean": _round(total / count),
                "share_above_95": _round(above / count),
                "share_below_05": _round(below / count),
            }
    return summary


@cache
def _cached_tail_points(dof: int) -> tuple[float, float]:
    return tail_points(dof)


def _round(value: float) -> float | None:
    return round(float(value), 6) if np.isfinite(value) else None
