"""What the others say (vehicle.trust.hearsay) and the record a neighbour earns (vehicle.trust.neighbours): more
than f believed accusers distrust a neighbour the vehicle cannot judge, never one it judges
consistent; accusers contradicted by the vehicle's own evidence are no longer heard, and said so
once; many accusers make the vehicle's own tests more watchful; a verdict on others' word holds
at least min_hold_s; each relapse doubles the probation, and a record is forgiven with time; in its
first seconds of trust, and of a neighbour it has just begun to range, a vehicle waits for its own
evidence."""

import dataclasses

import numpy as np

from tests.unit.vehicle.trust import neighbour_streams
from tests.unit.vehicle.trust.neighbour_streams import PERIOD_US
from vehicle.trust.hearsay import Contradiction, hear
from vehicle.trust.neighbours import NeighbourBook, Verdict

ME, LIAR = 1, 3
SPEC = dataclasses.replace(neighbour_streams.SPEC, max_compromised=2)  # told f = 2: it takes 3 believed accusers
F = SPEC.max_compromised


def stream(*args, **kwargs):
    return neighbour_streams.stream(*args, **{"spec": SPEC, **kwargs})


HOLD_US = round(SPEC.min_hold_s * 1e6)
WAIT_US = round((SPEC.window_s + SPEC.decorrelation_s) * 1e6)  # the time its own tests need to judge


def seasoned() -> NeighbourBook:
    """The book of a vehicle well past its first seconds of trust."""
    return NeighbourBook(started_us=-10 * WAIT_US)


def _accuse(book, accusers, accused, t_us, spec=SPEC):
    changes = []
    for j in accusers:
        changes += hear(book, spec, j, frozenset(accused), t_us, ME)
    return changes


def test_f_accusers_change_nothing_and_f_plus_one_distrust_a_neighbour_the_vehicle_cannot_judge():
    book = seasoned()
    assert _accuse(book, range(4, 4 + F), {LIAR}, 0) == [] and book.trusts(LIAR)
    (verdict,) = _accuse(book, [4 + F], {LIAR}, 0)
    assert (verdict.neighbour, verdict.trusted, verdict.reason) == (LIAR, False, "accused by v4, v5, v6")
    assert book.accused() == ()  # on others' word: not passed on


def test_a_verdict_on_others_word_holds_min_hold_s_before_their_retraction_counts():
    book = seasoned()
    _accuse(book, [4, 5, 6], {LIAR}, 0)
    assert _accuse(book, [6], set(), HOLD_US - 1) == [] and not book.trusts(LIAR)  # held
    (again,) = _accuse(book, [6], set(), HOLD_US)
    assert (again.trusted, again.reason) == (True, "no longer accused") and book.trusts(LIAR)
    assert _accuse(book, [6], {LIAR}, HOLD_US + 1) == [] and book.trusts(LIAR)  # held the other way too


def test_no_number_of_accusers_outweighs_a_neighbour_the_vehicle_ranges_and_finds_consistent():
    """Five accusers, repeating at every broadcast for 60 s: the neighbour stays believed, each
    accuser is contradicted once (one notice each, not one per broadcast) and no longer heard."""
    rng = np.random.default_rng(21)
    book = NeighbourBook()
    stream(book, 2, np.zeros((100, 2)), rng)  # ranged for 20 s
    changes = []
    accuse = lambda t: changes.extend(_accuse(book, range(4, 9), {2}, t))  # noqa: E731
    stream(book, 2, np.zeros((300, 2)), rng, start_us=100 * PERIOD_US, between=accuse)
    assert book.trusts(2)
    assert not [c for c in changes if isinstance(c, Verdict)], changes
    assert sorted(c.accuser for c in changes) == [4, 5, 6, 7, 8]
    assert all(c.accused == 2 for c in changes)
    # the same five now accuse a neighbour the vehicle cannot judge: their word counts for nothing
    assert _accuse(book, range(4, 9), {LIAR}, 300 * PERIOD_US) == [] and book.trusts(LIAR)


def test_a_contradicted_accuser_is_heard_again_after_discredit_s():
    rng = np.random.default_rng(22)
    book = seasoned()
    stream(book, 2, np.zeros((150, 2)), rng, between=lambda t: _accuse(book, [4], {2}, t))
    assert 4 in book.contradicted
    later = book.contradicted[4] + round(SPEC.discredit_s * 1e6)
    assert _accuse(book, [4, 5, 6], {LIAR}, later - 1) == []  # v4 not heard yet: two accusers
    (verdict,) = _accuse(book, [4], {LIAR}, later)
    assert not verdict.trusted and verdict.reason == "accused by v4, v5, v6"


def test_accusers_make_the_vehicles_own_tests_watchful_and_a_neighbour_it_cannot_clear_is_not_contradicted():
    """A neighbour 0.62 m off along one axis: its bias statistic over the long window (about 32) lies
    between the watchful bound (25) and the usual one (40). Unaccused it stays believed; accused by
    f + 1 from the start, the vehicle waits for its own evidence rather than distrust it on their
    word, then distrusts it on that evidence, watchfully judged (a first-hand verdict). Nobody is
    contradicted."""
    offsets = np.tile([0.62, 0.0], (150, 1))
    quiet = NeighbourBook()
    assert stream(quiet, 2, offsets, np.random.default_rng(23)) == []
    book = NeighbourBook()
    changes = []
    verdicts = stream(
        book, 2, offsets, np.random.default_rng(23), between=lambda t: changes.extend(_accuse(book, [4, 5, 6], {2}, t))
    )
    assert [(v.trusted, v.reason.split(" ")[0]) for v in verdicts] == [(False, "biased")]
    assert not [c for c in changes if isinstance(c, Verdict)]  # nothing on their word
    assert book.accused() == (2,) and not [c for c in changes if isinstance(c, Contradiction)]


def test_fresh_evidence_of_its_own_clears_a_neighbour_distrusted_on_others_word():
    rng = np.random.default_rng(24)
    book = seasoned()
    _accuse(book, [4, 5, 6], {LIAR}, 0)
    assert not book.trusts(LIAR)
    verdicts = stream(book, LIAR, np.zeros((30, 2)), rng, start_us=PERIOD_US)  # a window of its own fixes
    assert [(v.trusted, v.reason) for v in verdicts] == [(True, "consistent here")] and book.trusts(LIAR)
    assert _accuse(book, [4, 5, 6], {LIAR}, 30 * PERIOD_US) == []  # not yet evidence to hold against them
    stream(book, LIAR, np.zeros((80, 2)), rng, start_us=31 * PERIOD_US)
    # ranged consistently over the whole long window: the accusers, repeating themselves, are contradicted
    changes = _accuse(book, [4, 5, 6], {LIAR}, 110 * PERIOD_US)
    assert [c.accuser for c in changes if isinstance(c, Contradiction)] == [4, 5, 6] and book.trusts(LIAR)


def test_the_old_rule_lets_a_quorum_of_two_outweigh_the_vehicles_own_evidence():
    """The control (monitor.rule = quorum-only, f = 1): the hole this module closes."""
    old = dataclasses.replace(SPEC, hearsay_over_evidence=True, max_compromised=1)
    rng = np.random.default_rng(25)
    book = NeighbourBook()
    changes = []
    stream(
        book, 2, np.zeros((50, 2)), rng, spec=old, between=lambda t: changes.extend(_accuse(book, [4, 5], {2}, t, old))
    )
    assert not book.trusts(2) and [(c.neighbour, c.trusted) for c in changes] == [(2, False)]


def test_each_relapse_doubles_the_probation():
    """A liar that lies 10 s, behaves until trusted again, lies again: 10 s (here 20 s: the lie stays in
    the long window that long), 20 s, 40 s of probation."""
    rng = np.random.default_rng(26)
    book = NeighbourBook()
    start, probations = 0, []
    for _ in range(3):
        lie = stream(book, LIAR, np.full((50, 2), 30.0), rng, start_us=start)
        assert [v.trusted for v in lie] == [False]
        start += 50 * PERIOD_US
        (back,) = stream(book, LIAR, np.zeros((1000, 2)), rng, start_us=start)[:1]
        probations.append((back.stamp_us - start) * 1e-6)
        start = back.stamp_us + PERIOD_US
    # the first: until the lie's fixes leave the long window's bias test (20 s)
    assert probations[0] >= SPEC.long_window_s and 20 <= probations[1] < 22 and 40 <= probations[2] < 42, probations


def test_the_record_survives_the_neighbours_silence_and_is_forgiven_with_time():
    """A neighbour that goes quiet (a restart) and comes back keeps its record; believed for
    forgive_s, it is forgiven one verdict."""
    rng = np.random.default_rng(27)
    book = NeighbourBook()
    stream(book, LIAR, np.full((50, 2), 30.0), rng)
    (back,) = stream(book, LIAR, np.zeros((200, 2)), rng, start_us=50 * PERIOD_US)
    # silent for 60 s, then lying again: its second verdict
    silent_until = back.stamp_us + round(60e6)
    stream(book, LIAR, np.full((50, 2), 30.0), rng, start_us=silent_until)
    assert book.records[LIAR].verdicts == 2
    assert book.records[LIAR].probation_us(SPEC) == round(2 * SPEC.retrust_s * 1e6)
    start = silent_until + 50 * PERIOD_US
    (back,) = stream(book, LIAR, np.zeros((200, 2)), rng, start_us=start)
    # believed for forgive_s and more: one verdict forgiven, so the next is its second again, not its third
    later = back.stamp_us + round(SPEC.forgive_s * 1e6) + PERIOD_US
    stream(book, LIAR, np.full((50, 2), 30.0), rng, start_us=later)
    assert book.records[LIAR].verdicts == 2


def test_accusations_by_the_accused_of_the_vehicle_itself_or_by_the_distrusted_do_not_count():
    rng = np.random.default_rng(28)
    book = seasoned()
    assert not stream(book, 4, np.full((20, 2), 30.0), rng)[0].trusted  # v4 distrusted first-hand
    assert _accuse(book, [4, 5, 6], {LIAR, ME}, 4_000_000) == []  # v4's word is worth nothing here
    assert book.trusts(LIAR) and ME not in book.records
    assert _accuse(book, [LIAR], {LIAR}, 4_000_000) == []  # nor the liar's of itself
    (verdict,) = _accuse(book, [7], {LIAR}, 4_000_000)
    assert verdict.reason == "accused by v5, v6, v7"


def test_a_caught_liar_that_goes_on_to_drift_slowly_does_not_earn_trust_back_while_it_drifts():
    """The relapse profile: 8 s grossly off, then an offset growing 0.03 m/s from zero (0.06 sigma a
    second here). Distrusted at once and never trusted again in 3 minutes. Controls: the same liar
    turning honest after its gross phase is trusted again, and so is the drift when trust comes back
    on the watchful bound (25) instead of the clearing one (12)."""
    gross = np.full((40, 2), 30.0)
    cases = ((0.03, SPEC, False), (0.0, SPEC, True), (0.03, dataclasses.replace(SPEC, clear_bias=25.0), True))
    for growth, spec, trusted_again in cases:
        rng = np.random.default_rng(29)
        book = NeighbourBook()
        drift = np.outer(np.arange(900) * PERIOD_US * 1e-6 * growth, [1.0, 0.0])
        verdicts = stream(book, LIAR, np.concatenate([gross, drift]), rng, spec=spec)
        assert not verdicts[0].trusted
        assert any(v.trusted for v in verdicts) == trusted_again, (growth, spec.clear_bias, verdicts)


def test_in_its_first_seconds_a_vehicle_waits_for_its_own_evidence_before_a_quorums_word():
    """Two insiders (f = 1) accuse an honest neighbour in every broadcast from the first second: the
    vehicle ranges it and never distrusts it; once its evidence spans the long window, the
    accusers are contradicted."""
    spec = dataclasses.replace(SPEC, max_compromised=1)
    rng = np.random.default_rng(30)
    book = NeighbourBook()
    changes = []
    accuse = lambda t: changes.extend(_accuse(book, [4, 5], {2}, t, spec))  # noqa: E731
    verdicts = stream(book, 2, np.zeros((150, 2)), rng, spec=spec, between=accuse)
    assert verdicts == [] and not [c for c in changes if isinstance(c, Verdict)] and book.trusts(2)
    assert sorted(c.accuser for c in changes if isinstance(c, Contradiction)) == [4, 5]


def test_after_its_first_seconds_a_neighbour_it_does_not_range_is_distrusted_on_a_quorums_word():
    book = NeighbourBook()
    assert _accuse(book, [4, 5, 6], {LIAR}, 0) == [] and book.trusts(LIAR)  # its first seconds
    assert _accuse(book, [4, 5, 6], {LIAR}, WAIT_US - 1) == [] and book.trusts(LIAR)
    (verdict,) = _accuse(book, [4, 5, 6], {LIAR}, WAIT_US)
    assert not verdict.trusted and verdict.reason == "accused by v4, v5, v6"


def test_a_neighbour_just_met_is_judged_on_the_vehicles_own_evidence_first():
    """A seasoned vehicle begins to range neighbour 2, and from its second fix on a quorum accuses
    it: the vehicle waits for its own window of fixes, which clears it; a neighbour it does not
    range is distrusted at once."""
    rng = np.random.default_rng(31)
    book = seasoned()
    changes = []
    accuse = lambda t: t and changes.extend(_accuse(book, [4, 5, 6], {2}, t))  # noqa: E731
    verdicts = stream(book, 2, np.zeros((60, 2)), rng, between=accuse)
    assert verdicts == [] and not [c for c in changes if isinstance(c, Verdict)] and book.trusts(2)
    (verdict,) = _accuse(book, [4, 5, 6], {LIAR}, 60 * PERIOD_US)
    assert not verdict.trusted
