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
- **an implausible claim**: its last ``min_fixes`` broadcasts each claim a position variance (the
  covariance's smallest eigenvalue) below ``implausible_ratio`` times the smallest this vehicle has
  had itself and any other neighbour has claimed over the long window. Vehicles of one swarm share
  their datasheets, so no honest one is known ten times better (in variance) than all the others
  ever were; a covariance shrunk on purpose makes every fix with it a strong pull, and the
  innovations alone do not show it when the observer's own uncertainty dominates them. Such a fix
  is not fused even before the neighbour is distrusted (``plausible``);
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
neighbour's fixes are still judged but not fused; it is trusted again after ``retrust_s`` of passing
every test. What the others say counts too (``hear``): each broadcast names whom its sender
distrusts on its own evidence, and a neighbour that ``quorum`` believed vehicles accuse is
distrusted on their word. The believed neighbours' recent fixes also have a say on the vehicle's own
GNSS: a position reset that they speak against is refused (``disagreement``). The thresholds are set
from clean runs (no liar: the honest world, jamming, link faults; docs/liars.md), well above what
those reach. The statistics of one neighbour's fixes live in vehicle.neighbour_fixes. Pure; the
record lives in the filter's state, so a fusion-horizon replay restores it with everything else.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from vehicle.neighbour_fixes import Fix, effective_count, window_stats


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
    implausible_ratio: float = 0.1  # a claimed position variance below this times the best of the others'
    quorum: int = 2  # believed vehicles whose broadcasts must accuse a neighbour to distrust it on their word


@dataclass
class NeighbourRecord:
    """One neighbour's fixes of the long window, and whether it is believed."""

    fixes: deque = field(default_factory=deque)
    distrusted: bool = False
    passing_since_us: int | None = None  # while distrusted: every test has passed since then
    reason: str = ""
    hearsay: str = ""  # not "": distrusted on the word of others (who accuse it)

    def copy(self) -> NeighbourRecord:
        return NeighbourRecord(deque(self.fixes), self.distrusted, self.passing_since_us, self.reason, self.hearsay)

    @property
    def believed(self) -> bool:
        return not self.distrusted and not self.hearsay


@dataclass
class NeighbourBook:
    """Every neighbour's record, the smallest position variance the vehicle has had itself, and whom
    each neighbour's latest broadcast accused: {accuser: (stamp us, accused)}."""

    records: dict[int, NeighbourRecord] = field(default_factory=dict)
    own_best_m2: float = math.inf
    accusations: dict[int, tuple[int, frozenset[int]]] = field(default_factory=dict)

    def copy(self) -> NeighbourBook:
        return NeighbourBook({j: r.copy() for j, r in self.records.items()}, self.own_best_m2, dict(self.accusations))

    def best_claim_m2(self, besides: int) -> float:
        """The smallest position variance this vehicle has had, or any neighbour but ``besides`` has
        claimed in its record."""
        claims = (f.claimed_m2 for j, r in self.records.items() if j != besides for f in r.fixes)
        return min(claims, default=self.own_best_m2) if self.records else self.own_best_m2

    def trusts(self, neighbour: int) -> bool:
        record = self.records.get(neighbour)
        return record is None or record.believed

    def accused(self) -> tuple[int, ...]:
        """The neighbours distrusted on the vehicle's own evidence (what its broadcasts say)."""
        return tuple(sorted(j for j, r in self.records.items() if r.distrusted))


@dataclass(frozen=True)
class Verdict:
    """A neighbour's trust changed at ``stamp_us``: ``trusted`` False (distrusted) or True (again)."""

    stamp_us: int
    neighbour: int
    trusted: bool
    reason: str


def refused(book: NeighbourBook, neighbour: int) -> None:
    """The neighbour's latest fix was not fused (distrusted, or an implausible claim): it pulled nothing."""
    record = book.records.get(neighbour)
    if record is not None and record.fixes:
        record.fixes[-1] = dataclasses.replace(record.fixes[-1], fused=False)


def disagreement(book: NeighbourBook, spec: MonitorSpec, offset_m: np.ndarray, now_us: int) -> float:
    """How strongly the believed neighbours' recent fixes speak against moving the vehicle by
    ``offset_m`` (2,): the likelihood ratio of the fixes at the moved position against the present
    one, sum |w - G d|^2 - sum |w|^2 over the fixes of the last ``window_s`` that the gate passed
    (chi-square with 2 degrees of freedom when the move is as right as staying), counted with at most
    one fix per ``decorrelation_s`` per neighbour, as in the bias test. Neighbours that claim to be
    unsure say little: their G is small."""
    d0, d1 = float(offset_m[0]), float(offset_m[1])
    since, total = now_us - round(spec.window_s * 1e6), 0.0
    for record in book.records.values():
        if not record.believed:
            continue
        fixes = [f for f in record.fixes if f.stamp_us > since and not f.gated_out and math.isfinite(sum(f.whitened))]
        if not fixes:
            continue
        change = 0.0
        for f in fixes:
            g00, g01, g10, g11 = f.shift
            m0, m1 = f.whitened[0] - (g00 * d0 + g01 * d1), f.whitened[1] - (g10 * d0 + g11 * d1)
            change += m0 * m0 + m1 * m1 - f.whitened[0] ** 2 - f.whitened[1] ** 2
        total += change * effective_count(fixes, spec.decorrelation_s) / len(fixes)
    return total


def failure(record: NeighbourRecord, spec: MonitorSpec, now_us: int, best_m2: float = 0.0) -> str:
    """Why the neighbour's recent fixes are inconsistent ("" when they pass, or are too few to tell);
    ``best_m2``: the smallest position variance had or claimed by anyone else (the implausibility
    test; 0 or infinite: none)."""
    latest = list(record.fixes)[-spec.min_fixes :]
    if len(latest) == spec.min_fixes and all(f.gated_out for f in latest):
        return f"its last {spec.min_fixes} fixes fail the gate"
    plausible = spec.implausible_ratio * best_m2 if math.isfinite(best_m2) else 0.0
    if len(latest) == spec.min_fixes and all(f.claimed_m2 < plausible for f in latest):
        ratio = best_m2 / max(max(f.claimed_m2 for f in latest), 1e-300)
        return f"claims {min(ratio, 999):.0f}x less variance than others"
    short = window_stats(record.fixes, now_us - round(spec.window_s * 1e6), spec.decorrelation_s)
    if short.fixes >= spec.min_fixes:
        if short.gated_out > spec.gate_fail_share * short.fixes:
            return f"{short.gated_out} of {short.fixes} fixes fail the gate"
        if short.mean_nis > spec.mean_nis:
            return f"mean NIS {short.mean_nis:.1f} over {short.fixes} fixes"
        if short.bias > spec.bias:
            return f"biased by {short.bias:.0f} over {short.fixes} fixes"
    long = window_stats(record.fixes, now_us - round(spec.long_window_s * 1e6), spec.decorrelation_s)
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
    reason = failure(record, spec, fix.stamp_us, _best_claim(book, spec, neighbour, record))
    if not record.distrusted:
        if reason and _credible(book, spec, neighbour, fix.stamp_us):
            record.distrusted, record.passing_since_us, record.reason = True, None, reason
            return Verdict(fix.stamp_us, neighbour, False, reason)
        return None
    if reason or window_stats(record.fixes, fix.stamp_us - round(spec.window_s * 1e6)).fixes < spec.min_fixes:
        record.passing_since_us = None
        return None
    record.passing_since_us = fix.stamp_us if record.passing_since_us is None else record.passing_since_us
    if fix.stamp_us - record.passing_since_us >= round(spec.retrust_s * 1e6):
        record.distrusted, record.passing_since_us, record.reason = False, None, ""
        return Verdict(fix.stamp_us, neighbour, True, "consistent again")
    return None


def hear(
    book: NeighbourBook, spec: MonitorSpec, accuser: int, accused: frozenset[int], t_us: int, me: int
) -> list[Verdict]:
    """Record whom ``accuser``'s broadcast at ``t_us`` says its monitor distrusts on its own evidence;
    a Verdict for each neighbour whose belief changes. A neighbour accused in the latest broadcasts
    (of the last ``long_window_s``) of at least ``quorum`` vehicles this one believes is distrusted
    on their word, and trusted again when fewer accuse it (one liar cannot accuse alone; accusations
    of this vehicle itself, or by the accused, do not count). Only first-hand verdicts are passed
    on, so a rumour cannot keep itself alive."""
    if accused:
        book.accusations[accuser] = (t_us, accused)
    else:
        book.accusations.pop(accuser, None)
    since = t_us - round(spec.long_window_s * 1e6)
    for j in [j for j, (stamp, _) in book.accusations.items() if stamp <= since]:
        del book.accusations[j]
    named = {k for _, who in book.accusations.values() for k in who}
    verdicts = []
    for k in sorted((named | {k for k, r in book.records.items() if r.hearsay}) - {me}):
        accusers = sorted(
            j for j, (_, who) in book.accusations.items() if k in who and j not in (k, me) and book.trusts(j)
        )
        record = book.records.setdefault(k, NeighbourRecord())
        before = record.believed
        record.hearsay = "accused by " + ", ".join(f"v{j}" for j in accusers) if len(accusers) >= spec.quorum else ""
        if record.believed != before:
            verdicts.append(Verdict(t_us, k, record.believed, record.hearsay or "no longer accused"))
    return verdicts


def plausible(book: NeighbourBook, spec: MonitorSpec, neighbour: int) -> bool:
    """Whether the neighbour's latest fix claims a plausible covariance (the implausibility test on
    one fix): a fix that claims less is not fused, whether or not the neighbour is distrusted yet."""
    record = book.records.get(neighbour)
    if record is None or not record.fixes:
        return True
    best_m2 = _best_claim(book, spec, neighbour, record)
    return not (math.isfinite(best_m2) and record.fixes[-1].claimed_m2 < spec.implausible_ratio * best_m2)


def _best_claim(book: NeighbourBook, spec: MonitorSpec, neighbour: int, record: NeighbourRecord) -> float:
    """The implausibility test's reference (NeighbourBook.best_claim_m2), looked up only when the
    neighbour's latest claim is below ``implausible_ratio`` times the vehicle's own best (else the
    test passes whatever the others claim: the reference is at most the vehicle's own best)."""
    if not record.fixes or record.fixes[-1].claimed_m2 >= spec.implausible_ratio * book.own_best_m2:
        return book.own_best_m2
    return book.best_claim_m2(neighbour)


def _credible(book: NeighbourBook, spec: MonitorSpec, accused: int, t_us: int) -> bool:
    """The vehicle has grounds to trust itself over ``accused``: another believed neighbour's recent
    fixes pass every test (its own GNSS is no such ground: a spoofed receiver agrees with the filter
    it drags)."""
    since = t_us - round(spec.window_s * 1e6)
    return any(
        j != accused
        and r.believed
        and window_stats(r.fixes, since).fixes >= spec.min_fixes
        and not failure(r, spec, t_us)
        for j, r in book.records.items()
    )
