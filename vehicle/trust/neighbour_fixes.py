"""One neighbour's fixes as its monitor keeps them (vehicle.trust.neighbours), and what they say over a
window: each fix's innovation y (2,) whitened by its covariance S (w = L^-1 y, S = L L^T: a standard
normal pair for a consistent neighbour), the window's gate failures, mean NIS and bias (n_eff
|mean w|^2, chi-square with 2 degrees of freedom, counting at most one fix per decorrelation time),
and how far the fused ones may have pulled the observer. Pure; on floats (a fix a cycle per
neighbour: no numpy on the hot path)."""

from __future__ import annotations

import bisect
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from bus.once import computed_once
from vehicle.models.kalman import UpdateResult

BIAS_CLIP = 4.0  # whitened innovations longer than this count as this long in the bias test


@dataclass(frozen=True)
class Fix:
    """One fix as the monitor keeps it: stamp, NIS, whitened innovation (2 floats), gated out, and
    the innovation itself ([range m, bearing rad])."""

    stamp_us: int
    nis: float
    whitened: tuple[float, float]
    gated_out: bool
    innovation: tuple[float, float] = (0.0, 0.0)
    claimed_m2: float = math.inf  # the smallest eigenvalue of the neighbour's claimed position covariance
    fused: bool = True  # False: the gate refused it, or the vehicle did not believe it (``refused``)
    shift: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # G = d w / d(own position), row by row (1/m)
    range_m: float = 0.0  # the measured range

    # what every window over the fix needs, computed once (a fix is in some 100 windows)
    @computed_once
    def finite(self) -> bool:
        return math.isfinite(self.whitened[0]) and math.isfinite(self.whitened[1])

    @computed_once
    def clipped(self) -> tuple[float, float]:
        """The whitened innovation shortened to at most BIAS_CLIP (the bias test's)."""
        return _clip(self.whitened)

    @computed_once
    def square(self) -> float:
        """|w|^2: the NIS as whitened."""
        return self.whitened[0] ** 2 + self.whitened[1] ** 2


@dataclass(frozen=True)
class WindowStats:
    """A neighbour's fixes over a window: how many, how many failed the gate, mean NIS, bias."""

    fixes: int
    gated_out: int
    mean_nis: float
    bias: float


def fix_of(
    t_us: int,
    result: UpdateResult,
    claimed_cov_m2: np.ndarray | None = None,
    own_jacobian: Sequence | None = None,
    range_m: float = 0.0,
) -> Fix | None:
    """The monitor's record of a fix from its update result (None when it did not say its innovation);
    ``claimed_cov_m2`` (2, 2): the neighbour's claimed position covariance; ``own_jacobian`` (2 x 2,
    indexed [row][column]): J = d h / d(own position) of the fix's prediction h, kept whitened (the
    innovation moves by -J d when the vehicle moves by d: ``disagreement``)."""
    if result.innovation is None or result.innovation_cov is None:
        return None
    whitened = whiten(result.innovation, result.innovation_cov)
    claimed = math.inf if claimed_cov_m2 is None else smallest_variance(claimed_cov_m2)
    innovation = tuple(result.innovation[:2])
    shift = (0.0, 0.0, 0.0, 0.0)
    if own_jacobian is not None:
        (j00, j01), (j10, j11) = own_jacobian
        g00, g10 = whiten((j00, j10), result.innovation_cov)
        g01, g11 = whiten((j01, j11), result.innovation_cov)
        shift = (g00, g01, g10, g11)
    return Fix(t_us, result.nis, whitened, not result.accepted, innovation, claimed, result.accepted, shift, range_m)


def smallest_variance(covariance_m2: np.ndarray) -> float:
    """The smallest eigenvalue (m^2) of a symmetric 2 x 2 position covariance (NaN: 0, a claim of
    certainty)."""
    a, b, d = float(covariance_m2[0, 0]), float(covariance_m2[0, 1]), float(covariance_m2[1, 1])
    value = 0.5 * (a + d) - math.sqrt(0.25 * (a - d) ** 2 + b * b)
    return value if math.isfinite(value) else 0.0


def pull_m2(record: Sequence[Fix], since_us: int, decorrelation_s: float) -> float:
    """How far (squared, m^2) a neighbour's fixes ``record`` fused since ``since_us`` may have pulled the
    observer: the squared mean innovation (the bearing's at the latest fix's range), less what
    noise alone would give it: scaled by max(0, 1 - 2 / b), b = n_eff |mean w|^2 the fixes' bias
    statistic (2 expected of consistent fixes, as in the bias test), so that fixes as consistent
    as an honest neighbour's pulled nothing."""
    fixes = [f for f in record if f.stamp_us > since_us and f.fused and math.isfinite(sum(f.whitened))]
    if not fixes:
        return 0.0
    range_m = record[-1].range_m
    mean_range = sum(f.innovation[0] for f in fixes) / len(fixes)
    mean_bearing = sum(f.innovation[1] for f in fixes) / len(fixes)
    w0 = sum(f.whitened[0] for f in fixes) / len(fixes)
    w1 = sum(f.whitened[1] for f in fixes) / len(fixes)
    bias = effective_count(fixes, decorrelation_s) * (w0 * w0 + w1 * w1)
    beyond_noise = max(0.0, 1.0 - 2.0 / bias) if bias > 0.0 else 0.0
    return (mean_range**2 + (mean_bearing * range_m) ** 2) * beyond_noise


def whiten(y: tuple[float, ...], S: tuple[float, ...]) -> tuple[float, float]:
    """L^-1 y for S = L L^T, S (a, b, d) a symmetric 2 x 2; infinite when S is not positive definite."""
    a, b, d = S
    if not a > 0.0:
        return math.inf, math.inf
    l11 = math.sqrt(a)
    l21 = b / l11
    rest = d - l21 * l21
    if not rest > 0.0:
        return math.inf, math.inf
    w0 = y[0] / l11
    return w0, (y[1] - l21 * w0) / math.sqrt(rest)


def window_stats(record: Sequence[Fix], since_us: int, decorrelation_s: float = 0.0) -> WindowStats:
    """A neighbour's fixes ``record`` stamped after ``since_us``. The mean NIS is over the fixes the gate passed;
    the bias over all of them, each whitened innovation shortened to at most ``BIAS_CLIP`` (a fix the
    gate refused is evidence of an offset, but one wild fix must not make a bias alone), counting at
    most one fix per ``decorrelation_s`` over the span they cover. One pass, in stamp order."""
    fixes = passed = finite = 0
    nis = m0 = m1 = 0
    first_us = last_us = 0
    for f in record:
        if f.stamp_us <= since_us:
            continue
        fixes += 1
        if not f.finite:
            continue
        if not finite:
            first_us = f.stamp_us
        finite += 1
        last_us = f.stamp_us
        c0, c1 = f.clipped
        m0 += c0
        m1 += c1
        if not f.gated_out:
            passed += 1
            nis += f.square
    if not passed:
        return WindowStats(fixes, fixes - passed, math.inf, math.inf)
    m0, m1 = m0 / finite, m1 / finite
    n_eff = (
        float(finite) if decorrelation_s <= 0.0 else min(finite, 1.0 + (last_us - first_us) * 1e-6 / decorrelation_s)
    )
    return WindowStats(fixes, fixes - passed, nis / passed, n_eff * (m0 * m0 + m1 * m1))


class FixWindow:
    """A neighbour's fixes in stamp order, with running sums that give ``window_stats`` over any
    suffix in O(log n) (a vehicle asks two windows of some 100 fixes for every fix it judges).

    Each entry keeps, after its fix, the running count of finite fixes, of fixes the gate passed,
    and the sums of the passed fixes' NIS and of the finite fixes' clipped whitened innovations; a
    window's sums are differences of two running ones (equal to ``window_stats``'s to rounding: a
    few 1e-16 of the running sums). Fixes leave from the old end (``popleft``); a fix out of stamp
    order makes every later question take the one-pass reference (``window_stats``)."""

    __slots__ = ("_base", "_entries", "_head", "_ordered", "_stamps")

    def __init__(
        self,
        entries: list | None = None,
        base: tuple = (0, 0, 0.0, 0.0, 0.0),
        ordered: bool = True,
        stamps: list[int] | None = None,
    ) -> None:
        self._entries: list[tuple] = [] if entries is None else entries  # (stamp, finite, passed, nis, m0, m1, fix)
        self._stamps: list[int] = [e[0] for e in self._entries] if stamps is None else stamps  # bisected keyless
        self._base = base  # the running (finite, passed, nis, m0, m1) before the first entry
        self._head = 0  # entries before it have left
        self._ordered = ordered

    def append(self, fix: Fix) -> None:
        finite, passed, nis, m0, m1 = self._running(len(self._entries))
        if self._head < len(self._entries):
            self._ordered = self._ordered and fix.stamp_us >= self._entries[-1][0]
        if fix.finite:
            c0, c1 = fix.clipped
            finite, m0, m1 = finite + 1, m0 + c0, m1 + c1
            if not fix.gated_out:
                passed, nis = passed + 1, nis + fix.square
        self._entries.append((fix.stamp_us, finite, passed, nis, m0, m1, fix))
        self._stamps.append(fix.stamp_us)

    def popleft(self) -> Fix:
        if self._head >= len(self._entries):
            raise IndexError("pop from an empty FixWindow")
        fix = self._entries[self._head][6]
        self._head += 1
        if self._head >= 64 and 2 * self._head >= len(self._entries):
            self._base = self._running(self._head)
            del self._entries[: self._head]
            del self._stamps[: self._head]
            self._head = 0
        return fix

    def _running(self, i: int) -> tuple:
        """The running sums before entry ``i``."""
        return self._entries[i - 1][1:6] if i > 0 else self._base

    def replace_last(self, fix: Fix) -> None:
        """The latest fix, said again with fields that no window statistic reads (``fused``)."""
        last = self._entries[-1]
        self._entries[-1] = (*last[:6], fix)

    def copy(self) -> FixWindow:
        head = self._head
        return FixWindow(self._entries[head:], self._running(head), self._ordered, self._stamps[head:])

    def latest(self, n: int) -> list[Fix]:
        """The newest ``n`` fixes (fewer when there are fewer), oldest first."""
        return [e[6] for e in self._entries[max(self._head, len(self._entries) - n) :]]

    def __len__(self) -> int:
        return len(self._entries) - self._head

    def __bool__(self) -> bool:
        return len(self._entries) > self._head

    def __iter__(self) -> Iterator[Fix]:
        return (self._entries[i][6] for i in range(self._head, len(self._entries)))

    def __getitem__(self, i: int) -> Fix:
        n = len(self)
        if not -n <= i < n:
            raise IndexError("FixWindow index out of range")
        return self._entries[self._head + i if i >= 0 else len(self._entries) + i][6]

    def stats(self, since_us: int, decorrelation_s: float = 0.0) -> WindowStats:
        """``window_stats`` of the fixes stamped after ``since_us``."""
        if not self._ordered:
            return window_stats(list(self), since_us, decorrelation_s)
        entries, end = self._entries, len(self._entries)
        start = bisect.bisect_right(self._stamps, since_us, self._head)
        fixes = end - start
        before, last = self._running(start), self._running(end)
        passed = last[1] - before[1]
        if not passed:
            return WindowStats(fixes, fixes - passed, math.inf, math.inf)
        finite = last[0] - before[0]
        nis = last[2] - before[2]
        m0 = (last[3] - before[3]) / finite
        m1 = (last[4] - before[4]) / finite
        n_eff = float(finite)
        if decorrelation_s > 0.0:  # the first and the last finite fix (a passed fix is finite: there is one)
            first, last_finite = start, end - 1
            while not entries[first][6].finite:
                first += 1
            while not entries[last_finite][6].finite:
                last_finite -= 1
            n_eff = min(finite, 1.0 + (entries[last_finite][0] - entries[first][0]) * 1e-6 / decorrelation_s)
        return WindowStats(fixes, fixes - passed, nis / passed, n_eff * (m0 * m0 + m1 * m1))


def effective_count(fixes: list[Fix], decorrelation_s: float) -> float:
    """How many independent fixes ``fixes`` (in stamp order, at least one) are worth: at most one per
    ``decorrelation_s`` of the span they cover (each one when it is 0)."""
    n = float(len(fixes))
    if decorrelation_s <= 0.0:
        return n
    span_s = (fixes[-1].stamp_us - fixes[0].stamp_us) * 1e-6
    return min(n, 1.0 + span_s / decorrelation_s)


def _clip(w: tuple[float, float]) -> tuple[float, float]:
    norm = math.hypot(*w)
    scale = BIAS_CLIP / norm if norm > BIAS_CLIP else 1.0
    return w[0] * scale, w[1] * scale
