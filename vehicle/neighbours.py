"""Which neighbours a vehicle believes: a per-neighbour consistency monitor for cooperative fixes.

A neighbour with valid credentials may still lie (or honestly broadcast an estimate that has gone
wrong: its own GNSS spoofed, a broken IMU). Its signature says who sent a broadcast, not whether it
is true, so each vehicle judges what every neighbour says by how its fixes agree with the vehicle's
own estimate, as the GNSS health monitor judges a receiver (``vehicle.gnss_health``). Every fix (a
range and bearing paired with the neighbour's broadcast) is an innovation y (2,) with covariance S;
whitened, w = L^-1 y (S = L L^T), it is a standard normal pair for a consistent neighbour. Per
neighbour:

- **gate failures** over the last ``window_s``: more than ``gate_fail_share`` of its fixes rejected
  by the single-fix gate (a gross lie fails every one);
- **NIS** over the last ``window_s``: the mean of w^T w, 2 for a consistent neighbour, above
  ``mean_nis`` (an over-confident covariance, or an offset inside each gate);
- **bias** over the last ``window_s`` and over the last ``long_window_s``: n_eff |mean w|^2, chi-square
  with 2 degrees of freedom for a consistent neighbour, above ``bias`` (an offset that grows slowly
  enough to pass every single-fix gate still biases the mean, as a GNSS spoofer does). Successive
  fixes of one neighbour are not independent (both estimates' errors wander over seconds, the more
  so without GNSS), so the mean's variance is not 1/n: n_eff counts the window's fixes at most one
  per ``decorrelation_s``.

A test needs ``min_fixes`` fixes in its window; the last ``min_fixes`` fixes all failing the gate
fail at once. A neighbour that fails is distrusted only if the vehicle has grounds to trust itself
over it: another believed neighbour passing every test over the same window (when every neighbour
disagrees with a vehicle, the vehicle is the likelier one to be wrong, and it accuses nobody; its
own GNSS is no such ground, since a spoofed receiver agrees with the filter it drags). A distrusted
neighbour's fixes are still judged but not fused; it is trusted again after ``retrust_s`` of passing every test. The
thresholds are set from clean runs (no liar: the honest world, jamming, link faults; docs/liars.md),
well above what those reach. Pure; the record lives in the filter's state, so a fusion-horizon
replay restores it with everything else.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from vehicle.kalman import UpdateResult

BIAS_CLIP = 4.0  # whitened innovations longer than this count as this long in the bias test


@dataclass(frozen=True)
class MonitorSpec:
    window_s: float = 5.0
    long_window_s: float = 20.0
    min_fixes: int = 8
    gate_fail_share: float = 0.5  # more than this share of the window's fixes rejected by the gate
    mean_nis: float = 12.0  # window mean NIS (2 expected)
    bias: float = 40.0  # n_eff |mean whitened innovation|^2 (chi-square, 2 dof: P(> 40) = 2e-9)
    decorrelation_s: float = 1.0  # fixes closer than this count as one in the bias test (n_eff)
    retrust_s: float = 10.0


@dataclass(frozen=True)
class Fix:
    """One fix as the monitor keeps it: stamp, NIS, whitened innovation (2 floats), gated out, and
    the innovation itself ([range m, bearing rad])."""

    stamp_us: int
    nis: float
    whitened: tuple[float, float]
    gated_out: bool
    innovation: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class WindowStats:
    """A neighbour's fixes over a window: how many, how many failed the gate, mean NIS, bias."""

    fixes: int
    gated_out: int
    mean_nis: float
    bias: float


@dataclass
class NeighbourRecord:
    """One neighbour's fixes of the long window, and whether it is believed."""

    fixes: deque = field(default_factory=deque)
    distrusted: bool = False
    passing_since_us: int | None = None  # while distrusted: every test has passed since then
    reason: str = ""

    def copy(self) -> NeighbourRecord:
        return NeighbourRecord(deque(self.fixes), self.distrusted, self.passing_since_us, self.reason)


@dataclass
class NeighbourBook:
    """Every neighbour's record."""

    records: dict[int, NeighbourRecord] = field(default_factory=dict)

    def copy(self) -> NeighbourBook:
        return NeighbourBook({j: r.copy() for j, r in self.records.items()})

    def trusts(self, neighbour: int) -> bool:
        record = self.records.get(neighbour)
        return record is None or not record.distrusted


@dataclass(frozen=True)
class Verdict:
    """A neighbour's trust changed at ``stamp_us``: ``trusted`` False (distrusted) or True (again)."""

    stamp_us: int
    neighbour: int
    trusted: bool
    reason: str


def fix_of(t_us: int, result: UpdateResult) -> Fix | None:
    """The monitor's record of a fix from its update result (None when it did not say its innovation)."""
    if result.innovation is None or result.innovation_cov is None:
        return None
    whitened = whiten(result.innovation, result.innovation_cov)
    return Fix(t_us, result.nis, whitened, not result.accepted, tuple(result.innovation[:2]))


def pull_m2(record: NeighbourRecord, since_us: int, range_m: float) -> float:
    """How far (squared, m^2) the neighbour's fused fixes since ``since_us`` may have pulled the
    observer: the squared mean innovation, the bearing's at ``range_m``."""
    fixes = [f for f in record.fixes if f.stamp_us > since_us and not f.gated_out]
    if not fixes:
        return 0.0
    mean_range = sum(f.innovation[0] for f in fixes) / len(fixes)
    mean_bearing = sum(f.innovation[1] for f in fixes) / len(fixes)
    return mean_range**2 + (mean_bearing * range_m) ** 2


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


def window_stats(record: NeighbourRecord, since_us: int, decorrelation_s: float = 0.0) -> WindowStats:
    """The record's fixes stamped after ``since_us``. The mean NIS is over the fixes the gate passed;
    the bias over all of them, each whitened innovation shortened to at most ``BIAS_CLIP`` (a fix the
    gate refused is evidence of an offset, but one wild fix must not make a bias alone), counting at
    most one fix per ``decorrelation_s`` over the span they cover."""
    fixes = [f for f in record.fixes if f.stamp_us > since_us]
    finite = [f for f in fixes if all(map(math.isfinite, f.whitened))]
    passed = [f for f in finite if not f.gated_out]
    if not passed:
        return WindowStats(len(fixes), len(fixes) - len(passed), math.inf, math.inf)
    mean_nis = sum(f.whitened[0] ** 2 + f.whitened[1] ** 2 for f in passed) / len(passed)
    clipped = [_clip(f.whitened) for f in finite]
    m0 = sum(w0 for w0, _ in clipped) / len(clipped)
    m1 = sum(w1 for _, w1 in clipped) / len(clipped)
    n_eff = float(len(clipped))
    if decorrelation_s > 0.0:
        span_s = (finite[-1].stamp_us - finite[0].stamp_us) * 1e-6
        n_eff = min(n_eff, 1.0 + span_s / decorrelation_s)
    return WindowStats(len(fixes), len(fixes) - len(passed), mean_nis, n_eff * (m0 * m0 + m1 * m1))


def _clip(w: tuple[float, float]) -> tuple[float, float]:
    norm = math.hypot(*w)
    scale = BIAS_CLIP / norm if norm > BIAS_CLIP else 1.0
    return w[0] * scale, w[1] * scale


def failure(record: NeighbourRecord, spec: MonitorSpec, now_us: int) -> str:
    """Why the neighbour's recent fixes are inconsistent ("" when they pass, or are too few to tell)."""
    latest = list(record.fixes)[-spec.min_fixes :]
    if len(latest) == spec.min_fixes and all(f.gated_out for f in latest):
        return f"its last {spec.min_fixes} fixes fail the gate"
    short = window_stats(record, now_us - round(spec.window_s * 1e6), spec.decorrelation_s)
    if short.fixes >= spec.min_fixes:
        if short.gated_out > spec.gate_fail_share * short.fixes:
            return f"{short.gated_out} of {short.fixes} fixes fail the gate"
        if short.mean_nis > spec.mean_nis:
            return f"mean NIS {short.mean_nis:.1f} over {short.fixes} fixes"
        if short.bias > spec.bias:
            return f"biased by {short.bias:.0f} over {short.fixes} fixes"
    long = window_stats(record, now_us - round(spec.long_window_s * 1e6), spec.decorrelation_s)
    if long.fixes >= spec.min_fixes and long.bias > spec.bias and math.isfinite(long.bias):
        return f"biased by {long.bias:.0f} over {long.fixes} fixes"
    return ""


def see(book: NeighbourBook, spec: MonitorSpec, neighbour: int, fix: Fix) -> Verdict | None:
    """Record one fix of ``neighbour``; a Verdict when its trust changes."""
    record = book.records.setdefault(neighbour, NeighbourRecord())
    record.fixes.append(fix)
    horizon = fix.stamp_us - round(max(spec.window_s, spec.long_window_s) * 1e6)
    while record.fixes and record.fixes[0].stamp_us <= horizon:
        record.fixes.popleft()
    reason = failure(record, spec, fix.stamp_us)
    if not record.distrusted:
        if reason and _credible(book, spec, neighbour, fix.stamp_us):
            record.distrusted, record.passing_since_us, record.reason = True, None, reason
            return Verdict(fix.stamp_us, neighbour, False, reason)
        return None
    if reason or window_stats(record, fix.stamp_us - round(spec.window_s * 1e6)).fixes < spec.min_fixes:
        record.passing_since_us = None
        return None
    record.passing_since_us = fix.stamp_us if record.passing_since_us is None else record.passing_since_us
    if fix.stamp_us - record.passing_since_us >= round(spec.retrust_s * 1e6):
        record.distrusted, record.passing_since_us, record.reason = False, None, ""
        return Verdict(fix.stamp_us, neighbour, True, "consistent again")
    return None


def _credible(book: NeighbourBook, spec: MonitorSpec, accused: int, t_us: int) -> bool:
    """The vehicle has grounds to trust itself over ``accused``: another believed neighbour's recent
    fixes pass every test (its own GNSS is no such ground: a spoofed receiver agrees with the filter
    it drags)."""
    since = t_us - round(spec.window_s * 1e6)
    return any(
        j != accused
        and not r.distrusted
        and window_stats(r, since).fixes >= spec.min_fixes
        and not failure(r, spec, t_us)
        for j, r in book.records.items()
    )
