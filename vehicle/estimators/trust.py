"""What the filter does with its neighbour monitor (the pure tests are vehicle.trust.neighbours, what the
others' word is worth vehicle.trust.hearsay, the fixes' statistics vehicle.trust.neighbour_fixes): each
neighbour fix is judged before it is fused, with whom the neighbour's broadcast accuses; a verdict
against a neighbour (the vehicle's own, or on the word of a quorum of others where it cannot judge)
undoes what it may have pulled and is said in a notice, as is an accusation the vehicle's own
evidence contradicts; and the believed neighbours have a say on the vehicle's own GNSS position
resets. A part of ``Filter``
(``Filter.trust``; None with the monitor off); the record it keeps lives in
``FilterState.neighbours``, so a fusion-horizon replay restores it. Like every part it is handed
the state and the store, never the filter."""

from __future__ import annotations

import numpy as np

from bus import notices
from bus.statistics import gate_threshold
from vehicle.estimators.parts import Say, Store
from vehicle.estimators.state import SEVERITY_INFO, SEVERITY_WARNING, FilterState, Notice
from vehicle.models.cooperative_fixes import CooperativeFix, SeenFix
from vehicle.models.kalman import UpdateResult
from vehicle.trust.hearsay import Contradiction, hear
from vehicle.trust.neighbour_fixes import fix_of, pull_m2, smallest_variance
from vehicle.trust.neighbours import MonitorSpec, Verdict, plausible, refused, see
from vehicle.trust.reset_say import disagreement

IDENTITY = ((1.0, 0.0), (0.0, 1.0))


class NeighbourTrust:
    """The neighbour-monitor part of vehicle ``vehicle_id``'s filter, for the monitor's thresholds
    ``spec``; ``position_fixes``: its cooperative rule fuses the position a fix implies (``paper``),
    so a fix's Jacobian on the pose is the identity."""

    def __init__(self, spec: MonitorSpec, *, vehicle_id: int, position_fixes: bool = False) -> None:
        self.spec, self.vehicle_id, self.position_fixes = spec, vehicle_id, position_fixes

    def judge(
        self,
        s: FilterState,
        store: Store,
        neighbour: int,
        fix: CooperativeFix | SeenFix,
        result: UpdateResult,
        say: Say,
    ) -> bool:
        """Hand the fix to the neighbour monitor, with whom the neighbour's broadcast accuses; True when
        it may be fused (the neighbour believed and the fix's claimed covariance plausible). A
        neighbour found lying, by this vehicle or on the word of others, has been pulling this vehicle
        while it was believed: the position's variance grows by as much as the innovations of its
        fused fixes say the pull may be (as process noise: the correlations are kept), so that GNSS
        and the honest neighbours can pull it back (and its own broadcast does not pass the pull on
        as certain). What the monitor finds is said with ``say``."""
        book = s.neighbours
        changes = hear(book, self.spec, neighbour, fix.neighbour_accuses, fix.stamp_us, self.vehicle_id)
        claimed = fix.neighbour_cov_m2 if isinstance(fix, CooperativeFix) else fix.observer_cov[:2, :2]
        jacobian = IDENTITY if self.position_fixes else fix.own_jacobian(s.x)
        observed = fix_of(fix.stamp_us, result, claimed, jacobian, fix.range_m)
        believed = book.trusts(neighbour)
        if observed is not None:
            book.own_best_m2 = min(book.own_best_m2, smallest_variance(s.P[:2, :2]))
            verdict = see(book, self.spec, neighbour, observed)
            if verdict is not None and book.trusts(neighbour) != believed:  # else others' word decides
                changes.append(verdict)
            believed = book.trusts(neighbour) and plausible(book, self.spec, neighbour)
            if not believed:
                refused(book, neighbour)
        for change in changes:
            if isinstance(change, Verdict) and not change.trusted:
                since = change.stamp_us - round(self.spec.window_s * 1e6)
                store.inflate(
                    s,
                    [0, 1],
                    np.full(2, pull_m2(book.records[change.neighbour].fixes, since, self.spec.decorrelation_s)),
                )
            say(notice_of(change))
        return believed

    def allows_reset(self, s: FilterState, stamp_us: int, offset_m: np.ndarray) -> bool:
        """Whether the believed neighbours' recent fixes allow a GNSS position reset by ``offset_m``
        (2,): a spoofed receiver's fixes agree with each other and pass the reset's own tests, but
        not with neighbours that range the vehicle where it is (``vehicle.trust.reset_say.disagreement``
        within the reset's chi-square bound)."""
        limit = gate_threshold(2, s.gnss_health.spec.reset_probability)
        return disagreement(s.neighbours, self.spec, offset_m, stamp_us) <= limit


def notice_of(change: Verdict | Contradiction) -> Notice:
    """A neighbour's trust changed, or an accuser was contradicted: a STATUSTEXT, written by
    bus.notices (the ground station reads it back there and makes it an event)."""
    if isinstance(change, Contradiction):
        said = notices.Contradicted(change.accuser, change.accused)
        return Notice(change.stamp_us, SEVERITY_WARNING, notices.text_of(said))
    severity = SEVERITY_INFO if change.trusted else SEVERITY_WARNING
    said = notices.Verdict(change.neighbour, change.trusted, change.reason)
    return Notice(change.stamp_us, severity, notices.text_of(said))
