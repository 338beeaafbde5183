"""Which neighbours a vehicle believes: a per-neighbour consistency monitor for cooperative fixes.

A neighbour with valid credentials may still lie (or honestly broadcast an estimate that has gone
wrong: its own GNSS spoofed, a broken IMU). Its signature says who sent a broadcast, not whether it
is true, so each vehicle judges what every neighbour says by how its fixes agree with the vehicle's
own estimate, as the GNSS health monitor judges a receiver (``vehicle.estimators.gnss_health``). Every fix (a
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
neighbour's fixes are still judged but not fused; it is trusted again after passing every test for
a probation that grows with its record (``retrust_s`` at the first verdict, doubled at each
relapse, one relapse forgiven per ``forgive_s`` believed), its bias well inside even the watchful
bound throughout (``clear_bias``: a lie that grows slowly does not earn trust back while it grows);
while it has a record its tests are watchful (``watchful_bias``). What the others say
(``vehicle.trust.hearsay``) never outweighs what the vehicle finds itself: a neighbour it judges
(``judges``: fresh fixes of its own) is judged by its own tests, watchful while more than
``max_compromised`` believed vehicles accuse it; only a neighbour it cannot judge is distrusted on
the word of more than ``max_compromised`` of them. The believed neighbours' recent fixes also have a
say on the vehicle's own GNSS: a position reset that they speak against is refused
(``vehicle.trust.reset_say``). The thresholds are set from clean runs (no liar: the honest world, jamming,
link faults; docs/liars.md), well above what those reach. The statistics of one neighbour's fixes
live in vehicle.trust.neighbour_fixes. Pure; the record lives in the filter's state, so a fusion-horizon
replay restores it with everything else.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

from vehicle.trust.neighbour_fixes import Fix, FixWindow


@dataclass(frozen=True)
class MonitorSpec:
    window_s: float = 5.0
    long_window_s: float = 20.0
    min_fixes: int = 8
    gate_fail_share: float = 0.5  # more than this share of the window's fixes rejected by the gate
    mean_nis: float = 12.0  # window mean NIS (2 expected)
    bias: float = 40.0  # n_eff |mean whitened innovation|^2 (chi-square, 2 dof: P(> 40) = 2e-9)
    watchful_bias: float = 25.0  # the bias bound for a neighbour with a record or accused by more than f (P = 4e-6)
    clear_bias: float = 12.0  # own evidence clears an accused or a distrusted neighbour only with its bias below this
    decorrelation_s: float = 1.0  # fixes closer than this count as one in the bias test (n_eff)
    retrust_s: float = 10.0  # probation after a first verdict; each relapse doubles it
    forgive_s: float = 120.0  # one past verdict is forgiven per this long believed
    min_hold_s: float = 10.0  # a verdict on others' word holds at least this long
    hearsay_memory_s: float = 60.0  # an accusation not heard again for this long lapses
    discredit_s: float = 60.0  # an accuser contradicted by the vehicle's own evidence is not heard for this long
    implausible_ratio: float = 0.1  # a claimed position variance below this times the best of the others'
    max_compromised: int = 1  # f: hearsay needs more than f believed accusers (docs/security.md)
    hearsay_over_evidence: bool = False  # the quorum-only rule, kept as a control: a quorum's word decides

    @property
    def quorum(self) -> int:
        """Believed accusers it takes to distrust a neighbour on their word: more than f."""
        return self.max_compromised + 1


@dataclass
class NeighbourRecord:
    """One neighbour's fixes of the long window, and whether it is believed: ``distrusted`` on the
    vehicle's own evidence, ``hearsay`` (not "") on the word of others; ``verdicts``: its record
    (first-hand verdicts against it, less those forgiven), ``changed_us``: when the vehicle's
    belief in it last changed; ``accusers``: the believed vehicles that accuse it now."""

    fixes: FixWindow = field(default_factory=FixWindow)
    distrusted: bool = False
    passing_since_us: int | None = None  # while distrusted: every test has passed since then
    reason: str = ""
    hearsay: str = ""
    verdicts: int = 0
    changed_us: int | None = None
    accusers: tuple[int, ...] = ()

    def copy(self) -> NeighbourRecord:
        return dataclasses.replace(self, fixes=self.fixes.copy())

    @property
    def believed(self) -> bool:
        return not self.distrusted and not self.hearsay

    def standing(self, spec: MonitorSpec, now_us: int) -> int:
        """Its record at ``now_us``: the verdicts against it, less one per ``forgive_s`` it has been
        believed since the vehicle's belief in it last changed."""
        if self.distrusted or self.changed_us is None or not self.verdicts:
            return self.verdicts
        return max(0, self.verdicts - (now_us - self.changed_us) // round(spec.forgive_s * 1e6))

    def probation_us(self, spec: MonitorSpec) -> int:
        """How long a distrusted neighbour must pass every test to be trusted again: ``retrust_s``
        doubled for every verdict on its record before the present one."""
        return round(spec.retrust_s * 2.0 ** max(0, self.verdicts - 1) * 1e6)


@dataclass
class NeighbourBook:
    """Every neighbour's record, the smallest position variance the vehicle has had itself, whom
    each neighbour's latest broadcast accused: {accuser: (stamp us, accused)}, the accusers its own
    evidence contradicted: {accuser: stamp us of the latest such accusation}, and when it first
    heard a neighbour."""

    records: dict[int, NeighbourRecord] = field(default_factory=dict)
    own_best_m2: float = math.inf
    accusations: dict[int, tuple[int, frozenset[int]]] = field(default_factory=dict)
    contradicted: dict[int, int] = field(default_factory=dict)
    started_us: int | None = None  # when the vehicle first heard a neighbour (its first seconds of trust)

    def copy(self) -> NeighbourBook:
        return NeighbourBook(
            {j: r.copy() for j, r in self.records.items()},
            self.own_best_m2,
            dict(self.accusations),
            dict(self.contradicted),
            self.started_us,
        )

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
        record.fixes.replace_last(dataclasses.replace(record.fixes[-1], fused=False))


def failure(
    record: NeighbourRecord, spec: MonitorSpec, now_us: int, best_m2: float = 0.0, bias: float | None = None
) -> str:
    """Why the neighbour's recent fixes are inconsistent ("" when they pass, or are too few to tell);
    ``best_m2``: the smallest position variance had or claimed by anyone else (the implausibility
    test; 0 or infinite: none). The bias bound is ``bias``; None: ``watchful_bias`` while the
    neighbour has a record or more than f believed vehicles accuse it, else ``bias``."""
    latest = record.fixes.latest(spec.min_fixes)
    if len(latest) == spec.min_fixes and all(f.gated_out for f in latest):
        return f"its last {spec.min_fixes} fixes fail the gate"
    plausible = spec.implausible_ratio * best_m2 if math.isfinite(best_m2) else 0.0
    if len(latest) == spec.min_fixes and all(f.claimed_m2 < plausible for f in latest):
        ratio = best_m2 / max(max(f.claimed_m2 for f in latest), 1e-300)
        return f"claims {min(ratio, 999):.0f}x less variance than others"
    if bias is None:
        watchful = record.standing(spec, now_us) > 0 or len(record.accusers) >= spec.quorum
        bias = spec.watchful_bias if watchful else spec.bias
    short = record.fixes.stats(now_us - round(spec.window_s * 1e6), spec.decorrelation_s)
    if short.fixes >= spec.min_fixes:
        if short.gated_out > spec.gate_fail_share * short.fixes:
            return f"{short.gated_out} of {short.fixes} fixes fail the gate"
        if short.mean_nis > spec.mean_nis:
            return f"mean NIS {short.mean_nis:.1f} over {short.fixes} fixes"
        if short.bias > bias:
            return f"biased by {short.bias:.0f} over {short.fixes} fixes"
    long = record.fixes.stats(now_us - round(spec.long_window_s * 1e6), spec.decorrelation_s)
    if long.fixes >= spec.min_fixes and long.bias > bias and math.isfinite(long.bias):
        return f"biased by {long.bias:.0f} over {long.fixes} fixes"
    return ""


def judges(record: NeighbourRecord | None, spec: MonitorSpec, now_us: int, span_s: float | None = None) -> bool:
    """Whether the vehicle can judge the neighbour on its own evidence at ``now_us``: it has ranged it
    over the last ``span_s`` (``window_s`` when None): ``min_fixes`` fixes in it, the first within
    ``decorrelation_s`` of its start and the latest within ``decorrelation_s`` of now (a vehicle that
    ranged it before a lie began has no evidence of the lie, and a second of fixes shows no bias)."""
    fresh_us = round(spec.decorrelation_s * 1e6)
    if record is None or not record.fixes or now_us - record.fixes[-1].stamp_us > fresh_us:
        return False
    since = now_us - round((spec.window_s if span_s is None else span_s) * 1e6)
    recent = [f for f in record.fixes if f.stamp_us > since]
    return len(recent) >= spec.min_fixes and recent[0].stamp_us <= since + fresh_us


def consistent_here(book: NeighbourBook, spec: MonitorSpec, neighbour: int, now_us: int) -> bool:
    """Whether the vehicle's own evidence clears the neighbour at ``now_us``, strongly enough to hold
    an accusation of it against its accuser: it has ranged it over the whole long window, its fixes
    pass every test with a bias below ``clear_bias`` (well inside the watchful bound, so that a lie
    the evidence is still growing on is not cleared) and the vehicle has not distrusted it itself."""
    record = book.records.get(neighbour)
    return (
        record is not None
        and not record.distrusted
        and judges(record, spec, now_us, spec.long_window_s)
        and not failure(record, spec, now_us, _best_claim(book, spec, neighbour, record), bias=spec.clear_bias)
    )


def see(book: NeighbourBook, spec: MonitorSpec, neighbour: int, fix: Fix) -> Verdict | None:
    """Record one fix of ``neighbour``; a Verdict when the vehicle's own verdict on it changes, or
    when its own evidence clears a neighbour distrusted on the word of others."""
    record = book.records.get(neighbour)
    if record is None:  # (setdefault would build a record for every fix)
        record = book.records[neighbour] = NeighbourRecord()
    record.fixes.append(fix)
    now = fix.stamp_us
    horizon = now - round(max(spec.window_s, spec.long_window_s) * 1e6)
    while record.fixes and record.fixes[0].stamp_us <= horizon:
        record.fixes.popleft()
    best_m2 = _best_claim(book, spec, neighbour, record)
    if record.distrusted:  # trust is earned back only by evidence that clears it (as it clears an accused)
        reason = failure(record, spec, now, best_m2, bias=spec.clear_bias)
    else:
        reason = failure(record, spec, now, best_m2)
    if not record.distrusted:
        if reason and _credible(book, spec, neighbour, now):
            record.verdicts = record.standing(spec, now) + 1
            record.distrusted, record.passing_since_us, record.reason = True, None, reason
            record.changed_us = now
            return Verdict(now, neighbour, False, reason)
        if record.hearsay and not spec.hearsay_over_evidence and not reason and judges(record, spec, now):
            record.hearsay, record.changed_us = "", now
            return Verdict(now, neighbour, True, "consistent here")
        return None
    if reason or record.fixes.stats(now - round(spec.window_s * 1e6)).fixes < spec.min_fixes:
        record.passing_since_us = None
        return None
    record.passing_since_us = now if record.passing_since_us is None else record.passing_since_us
    if now - record.passing_since_us >= record.probation_us(spec):
        record.distrusted, record.passing_since_us, record.reason = False, None, ""
        record.changed_us = now
        return Verdict(now, neighbour, True, "consistent again")
    return None


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
        j != accused and r.believed and r.fixes.stats(since).fixes >= spec.min_fixes and not failure(r, spec, t_us)
        for j, r in book.records.items()
    )
