"""The neighbour monitor: a consistent neighbour is never distrusted; one whose fixes all fail the
gate is distrusted within a second or two; a slow drift that passes every gate is caught by the bias
of its innovations; an over-confident one by its NIS; a vehicle with no grounds to trust itself
accuses nobody; a distrusted neighbour is trusted again once it has been consistent for a while
(what the others say: test_hearsay)."""

import math

import numpy as np
import pytest

from tests.unit.vehicle.trust.neighbour_streams import PERIOD_US, SPEC, S, fix, stream, witness
from vehicle.models.kalman import UpdateResult
from vehicle.trust.neighbour_fixes import fix_of, pull_m2, whiten
from vehicle.trust.neighbours import NeighbourBook, plausible, see
from vehicle.trust.reset_say import disagreement


def test_whitening_makes_a_standard_pair():
    w = whiten((1.0, 2.0), (4.0, 2.0, 5.0))  # L = [[2, 0], [1, 2]]: w = L^-1 y = (0.5, 0.75)
    assert w == pytest.approx((0.5, 0.75))
    assert whiten((1.0, 1.0), (1.0, 2.0, 1.0)) == (math.inf, math.inf)  # not positive definite


def test_a_consistent_neighbour_is_never_distrusted():
    rng = np.random.default_rng(1)
    book = NeighbourBook()
    assert stream(book, 3, np.zeros((3000, 2)), rng) == []  # 10 minutes of fixes
    assert book.trusts(3)


def test_a_gross_liar_is_distrusted_once_its_last_min_fixes_fail_the_gate():
    rng = np.random.default_rng(2)
    book = NeighbourBook()
    verdicts = stream(book, 3, np.full((50, 2), 30.0), rng)
    assert verdicts and not verdicts[0].trusted and "fail the gate" in verdicts[0].reason
    assert verdicts[0].stamp_us <= SPEC.min_fixes * PERIOD_US and not book.trusts(3)


def test_a_slow_drift_that_passes_every_gate_is_caught_by_its_bias():
    rng = np.random.default_rng(3)
    book = NeighbourBook()
    drift = np.outer(np.arange(300) * PERIOD_US * 1e-6, [0.1, 0.0])  # 0.1 m/s: 0.02 m per fix
    verdicts = stream(book, 3, drift, rng)
    assert verdicts and "biased" in verdicts[0].reason
    offset_when_caught = 0.1 * verdicts[0].stamp_us * 1e-6
    assert offset_when_caught < 1.8  # below the single-fix gate (3.7 sigmas, 1.86 m): the fixes still pass it


def test_an_overconfident_neighbour_is_caught_by_its_nis():
    rng = np.random.default_rng(4)
    book = NeighbourBook()
    verdicts = []
    for k in range(100):  # its real scatter is 3 m where it claims 0.5 m
        witness(book, rng, k * PERIOD_US)
        y = rng.normal(0.0, 1.5, 2)
        verdict = see(book, SPEC, 3, fix(k * PERIOD_US, (float(y[0]), float(y[1])), gate=1e9))
        verdicts += [verdict] if verdict else []
    assert verdicts and "mean NIS" in verdicts[0].reason


def test_a_vehicle_without_grounds_to_trust_itself_accuses_nobody():
    """Every neighbour disagreeing with the vehicle: the vehicle is the likelier one to be wrong."""
    rng = np.random.default_rng(5)
    book = NeighbourBook()
    for k in range(100):
        for neighbour in (2, 3):
            y = rng.normal(0.0, 0.5, 2) + 5.0
            assert see(book, SPEC, neighbour, fix(k * PERIOD_US, (float(y[0]), float(y[1])))) is None
    assert book.trusts(2) and book.trusts(3)


def test_another_consistent_neighbour_is_grounds_enough():
    rng = np.random.default_rng(6)
    book = NeighbourBook()
    verdicts = []
    for k in range(100):
        y2 = rng.normal(0.0, 0.5, 2)
        see(book, SPEC, 2, fix(k * PERIOD_US, (float(y2[0]), float(y2[1]))))
        y3 = rng.normal(0.0, 0.5, 2) + 30.0
        verdict = see(book, SPEC, 3, fix(k * PERIOD_US, (float(y3[0]), float(y3[1]))))
        verdicts += [verdict] if verdict else []
    assert [v.neighbour for v in verdicts] == [3] and book.trusts(2)


def test_a_distrusted_neighbour_is_trusted_again_after_being_consistent_for_a_while():
    rng = np.random.default_rng(7)
    book = NeighbourBook()
    offsets = np.concatenate([np.full((50, 2), 30.0), np.zeros((200, 2))])
    verdicts = stream(book, 3, offsets, rng)
    assert [v.trusted for v in verdicts] == [False, True]
    assert verdicts[1].stamp_us - 50 * PERIOD_US >= SPEC.retrust_s * 1e6 and book.trusts(3)


def test_the_book_copies_independently():
    rng = np.random.default_rng(8)
    book = NeighbourBook()
    stream(book, 3, np.zeros((20, 2)), rng)
    twin = book.copy()
    stream(book, 3, np.full((20, 2), 30.0), rng, start_us=20 * PERIOD_US)
    assert not book.trusts(3) and twin.trusts(3) and len(twin.records[3].fixes) == 20


def _claiming(t_us: int, y, claimed_m2: float):
    """A consistent fix whose neighbour claims a position covariance of ``claimed_m2`` on each axis."""
    nis = (y[0] ** 2 + y[1] ** 2) / 0.25
    return fix_of(t_us, UpdateResult(True, nis, nis / 13.8, y, S), np.diag([claimed_m2, claimed_m2]))


@pytest.mark.parametrize("shrink, caught", [(1.0, False), (0.3, False), (0.01, True)])
def test_a_claim_far_below_everyone_elses_is_refused_at_once_and_distrusted_after_min_fixes(shrink, caught):
    """Vehicles of one swarm, one datasheet: an honest neighbour a few times better than the others
    is normal; one claiming 100 times less variance (innovations as consistent as the others') is not."""
    rng = np.random.default_rng(9)
    book = NeighbourBook(own_best_m2=0.04)  # the observer has been known to 0.2 m
    verdicts, refused = [], 0
    for k in range(60):
        t = k * PERIOD_US
        for neighbour, claim in ((2, 0.05), (3, 0.05 * shrink)):
            y = rng.normal(0.0, 0.5, 2)
            verdict = see(book, SPEC, neighbour, _claiming(t, (float(y[0]), float(y[1])), claim))
            verdicts += [verdict] if verdict else []
            refused += neighbour == 3 and not plausible(book, SPEC, 3)
    if not caught:
        assert verdicts == [] and refused == 0
        return
    assert refused == 60  # not one of its fixes fused, from the first
    assert [(v.neighbour, v.trusted) for v in verdicts] == [(3, False)] and "less variance" in verdicts[0].reason
    assert verdicts[0].stamp_us == (SPEC.min_fixes - 1) * PERIOD_US and book.trusts(2)


def test_a_vehicle_that_has_not_settled_yet_judges_claims_by_its_neighbours():
    """Its own best is still its wide prior: a neighbour's claim is compared with the others' too."""
    book = NeighbourBook(own_best_m2=25.0)
    for k in range(10):
        see(book, SPEC, 2, _claiming(k * PERIOD_US, (0.1, 0.1), 0.04))
        see(book, SPEC, 3, _claiming(k * PERIOD_US, (0.1, 0.1), 0.04))
    assert plausible(book, SPEC, 2) and plausible(book, SPEC, 3) and book.trusts(2) and book.trusts(3)
    see(book, SPEC, 3, _claiming(10 * PERIOD_US, (0.1, 0.1), 0.0004))
    assert not plausible(book, SPEC, 3)


def _ranged(t_us: int, y, sigma_m: float, toward: np.ndarray):
    """A fix whose range innovation y (m, 2,) has sigma ``sigma_m`` on each axis and moves by -toward . d
    when the vehicle moves by d (a neighbour in direction -toward; the bearing's row left at zero)."""
    S_fix = (sigma_m**2, 0.0, sigma_m**2)
    nis = (y[0] ** 2 + y[1] ** 2) / sigma_m**2
    J = np.array([toward, [0.0, 0.0]])
    return fix_of(t_us, UpdateResult(True, nis, nis / 13.8, y, S_fix), None, J)


@pytest.mark.parametrize("sigma_m, refused", [(0.5, True), (20.0, False)])
def test_neighbours_that_range_the_vehicle_where_it_is_speak_against_a_jump(sigma_m, refused):
    """A GNSS reset asks the believed neighbours (GnssHealth.check's may_reset): two of them, in
    different directions, whose fixes are consistent with the present position, speak against a 3 m
    jump by far more than the reset's chi-square bound (13.8), and not against staying; neighbours
    that claim to be unsure (20 m) say little either way. Evidence is counted one fix a second."""
    rng = np.random.default_rng(11)
    book = NeighbourBook()
    for k in range(25):
        for neighbour, toward in ((2, np.array([1.0, 0.0])), (4, np.array([0.0, 1.0]))):
            y = rng.normal(0.0, sigma_m, 2)
            see(book, SPEC, neighbour, _ranged(k * PERIOD_US, (float(y[0]), 0.0), sigma_m, toward))
    now = 24 * PERIOD_US
    jump = disagreement(book, SPEC, np.array([3.0, -2.0]), now)
    assert (jump > 13.8) == refused and abs(disagreement(book, SPEC, np.zeros(2), now)) < 1e-9
    assert disagreement(book, SPEC, np.array([3.0, -2.0]), now + round(SPEC.window_s * 1e6)) == 0.0  # all old


def test_neighbours_that_saw_the_vehicle_off_support_the_jump_back():
    """Fixes offset by the jump itself (the vehicle is 2 m off where they range it) favour it."""
    rng = np.random.default_rng(12)
    book = NeighbourBook()
    toward = np.array([1.0, 0.0])
    for k in range(25):
        y = rng.normal(0.0, 0.5) + 2.0  # the range says 2 m more than predicted: move 2 m along toward
        see(book, SPEC, 2, _ranged(k * PERIOD_US, (float(y), 0.0), 0.5, toward))
    assert disagreement(book, SPEC, np.array([2.0, 0.0]), 24 * PERIOD_US) < -13.8


def test_the_pull_undone_at_a_verdict_is_what_the_fixes_show_beyond_their_noise():
    """Consistent fixes pulled nothing as a rule (their mean innovation is noise: the bias statistic
    is 2 on average, and a pull is counted only beyond that); fixes 1 m off on the range pulled
    about 1 m^2."""
    rng = np.random.default_rng(14)

    def pull(offset_m: float) -> float:
        book = NeighbourBook()
        stream(book, 3, np.column_stack([np.full(25, offset_m), np.zeros(25)]), rng)
        return pull_m2(book.records[3].fixes, -1, SPEC.decorrelation_s)

    honest = [pull(0.0) for _ in range(40)]
    assert sum(p == 0.0 for p in honest) >= 20 and max(honest) < 0.1, honest
    biased = [pull(1.0) for _ in range(10)]
    assert all(0.5 <= p <= 1.5 for p in biased), biased  # (1 +- 0.1 m)^2, the noise of a 25-fix mean
