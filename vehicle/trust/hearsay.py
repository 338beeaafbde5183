"""What the others say about a neighbour, and what it is worth (the threat model: docs/security.md).

Each V2V broadcast names whom its sender distrusts on its own evidence (vehicle.process.v2v). Up to ``f``
(``MonitorSpec.max_compromised``) vehicles may be compromised: their signatures are valid and they
may accuse anyone, withhold accusations or fall silent. So what others say counts only this far:

- **never against first-hand evidence**: a neighbour the vehicle judges itself
  (``vehicle.trust.neighbours.judges``) is judged by the vehicle's own tests; more than ``f`` believed
  accusers only make those tests more watchful (``MonitorSpec.watchful_bias``);
- **a quorum larger than f where the vehicle cannot judge**: a neighbour it has no fresh fixes of
  is distrusted on the word of at least ``f + 1`` believed accusers, and such a verdict holds at
  least ``min_hold_s`` either way (no flapping as accusations come and go);
- **not before the vehicle could have judged**: in its first seconds of trust (a window and a
  decorrelation time from the first neighbour it heard) it has not had time to range anyone, and a
  neighbour it has only just begun to range (its fixes fresh, the first of them less than that long
  ago) is one it is about to judge: in both it waits for its own evidence rather than act on
  others' word (insiders accusing from the first second would otherwise have every honest vehicle
  distrust the others before anyone could range anyone);
- **accusers are judged too**: an accusation of a neighbour the vehicle's own evidence clears
  (``vehicle.trust.neighbours.consistent_here``) is contradicted. Its accuser is not heard for
  ``discredit_s`` after its latest contradicted accusation (a Contradiction when it starts: a
  notice, an event at the ground station);
- accusations by the accused, of the vehicle itself, or by a neighbour the vehicle does not believe
  do not count; an accusation not heard again within ``hearsay_memory_s`` lapses (a vehicle hears
  an accuser only while it ranges it, so an accusation out of earshot is not a retraction).

``MonitorSpec.hearsay_over_evidence`` keeps the rule this replaced (a quorum's word decides, the
vehicle's own evidence notwithstanding, and accusers are not judged) as a control. Pure.
"""

from __future__ import annotations

from dataclasses import dataclass

from vehicle.trust.neighbours import MonitorSpec, NeighbourBook, NeighbourRecord, Verdict, consistent_here, judges


@dataclass(frozen=True)
class Contradiction:
    """At ``stamp_us`` the vehicle's own evidence contradicted ``accuser``'s accusation of ``accused``,
    and ``accuser`` is no longer heard."""

    stamp_us: int
    accuser: int
    accused: int


def hear(
    book: NeighbourBook, spec: MonitorSpec, accuser: int, accused: frozenset[int], t_us: int, me: int
) -> list[Verdict | Contradiction]:
    """Record whom ``accuser``'s broadcast at ``t_us`` accuses; what changes: a Verdict for each
    neighbour whose belief changes on the others' word, a Contradiction when ``accuser`` starts
    being discredited."""
    if book.started_us is None:
        book.started_us = t_us
    if accused:
        book.accusations[accuser] = (t_us, accused)
    else:
        book.accusations.pop(accuser, None)
        if not book.accusations and not any(r.hearsay or r.accusers for r in book.records.values()):
            return []  # nobody accuses anyone and nobody stands accused: nothing below would change (every fix)
    since = t_us - round(spec.hearsay_memory_s * 1e6)
    for j in [j for j, (stamp, _) in book.accusations.items() if stamp <= since]:
        del book.accusations[j]
    changes: list[Verdict | Contradiction] = []
    if not spec.hearsay_over_evidence:
        changes += _judge_accuser(book, spec, accuser, accused - {me, accuser}, t_us)
    named = {k for _, who in book.accusations.values() for k in who}
    standing = {k for k, r in book.records.items() if r.hearsay or r.accusers}
    for k in sorted((named | standing) - {me}):
        record = book.records.setdefault(k, NeighbourRecord())
        record.accusers = tuple(_accusers(book, spec, k, me, t_us))
        verdict = _decide(record, spec, k, t_us, _may_judge_soon(book, record, spec, t_us))
        if verdict is not None:
            changes.append(verdict)
    return changes


def heard(book: NeighbourBook, spec: MonitorSpec, accuser: int, t_us: int) -> bool:
    """Whether ``accuser``'s accusations count at ``t_us``: believed, and not contradicted by the
    vehicle's own evidence within ``discredit_s``."""
    last = book.contradicted.get(accuser)
    recent = last is not None and t_us - last < spec.discredit_s * 1e6
    return book.trusts(accuser) and not (recent and not spec.hearsay_over_evidence)


def _accusers(book: NeighbourBook, spec: MonitorSpec, k: int, me: int, t_us: int) -> list[int]:
    """The heard vehicles whose standing accusations name ``k`` (not ``k`` itself, nor this vehicle)."""
    return sorted(
        j for j, (_, who) in book.accusations.items() if k in who and j not in (k, me) and heard(book, spec, j, t_us)
    )


def _may_judge_soon(book: NeighbourBook, record: NeighbourRecord, spec: MonitorSpec, t_us: int) -> bool:
    """Whether the vehicle is in its first seconds of trust, or has only just begun to range the
    neighbour of ``record`` (module docstring): a window and a decorrelation time, the time its own
    tests need to judge a neighbour it ranges."""
    wait_us = round((spec.window_s + spec.decorrelation_s) * 1e6)
    if book.started_us is not None and t_us - book.started_us < wait_us:
        return True
    fixes = record.fixes
    fresh = bool(fixes) and t_us - fixes[-1].stamp_us <= round(spec.decorrelation_s * 1e6)
    return fresh and t_us - fixes[0].stamp_us < wait_us


def _decide(record: NeighbourRecord, spec: MonitorSpec, k: int, t_us: int, judges_soon: bool) -> Verdict | None:
    """The others' word on ``k`` now: distrusted while a quorum accuses it and the vehicle cannot
    judge it, nor is about to (``judges_soon``) (whatever it judges, under the old rule); each change
    at least ``min_hold_s`` after the last one."""
    quorum = len(record.accusers) >= spec.quorum
    own_say = not spec.hearsay_over_evidence and (judges(record, spec, t_us) or judges_soon)
    word = "accused by " + ", ".join(f"v{j}" for j in record.accusers) if quorum and not own_say else ""
    if bool(word) == bool(record.hearsay):
        record.hearsay = word  # the same verdict; the accusers named as they stand
        return None
    held = record.changed_us is not None and t_us - record.changed_us < spec.min_hold_s * 1e6
    if held:
        return None
    before = record.believed
    record.hearsay = word
    if record.believed == before:
        return None
    record.changed_us = t_us
    return Verdict(t_us, k, record.believed, word or "no longer accused")


def _judge_accuser(
    book: NeighbourBook, spec: MonitorSpec, accuser: int, accused: frozenset[int], t_us: int
) -> list[Contradiction]:
    """An accusation of a neighbour the vehicle's own evidence clears counts against the accuser."""
    cleared = sorted(k for k in accused if consistent_here(book, spec, k, t_us))
    if not cleared:
        return []
    was_heard = heard(book, spec, accuser, t_us)
    book.contradicted[accuser] = t_us
    return [Contradiction(t_us, accuser, cleared[0])] if was_heard else []
