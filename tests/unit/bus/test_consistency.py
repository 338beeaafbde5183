"""Consistency statistics (bus.consistency) against chi-square draws: the block band holds a consistent
filter whose errors are autocorrelated, the per-epoch band does not, over- and under-confident filters
fall out on their side, and the tail shares are 5 % each when the covariance is honest."""

from __future__ import annotations

import numpy as np
import pytest

from bus.consistency import NIS_KINDS, ConsistencyTally, NisBook, consistency, nis_summary, tail_points
from bus.statistics import chi2_band

RATE_HZ, DURATION_S, TAU_S = 10.0, 660.0, 3.0


def correlated_nees(rng: np.random.Generator, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(t (N,) s, NEES (N,)) of a 3-dof error whose components are unit-variance AR(1) processes with
    correlation time TAU_S, judged under a covariance ``scale`` times too small (1: honest)."""
    t = np.arange(0.0, DURATION_S, 1.0 / RATE_HZ)
    a = np.exp(-1.0 / (RATE_HZ * TAU_S))
    shocks = rng.standard_normal((t.size, 3)) * np.sqrt(1.0 - a * a)
    error = np.empty_like(shocks)
    error[0] = rng.standard_normal(3)
    for k in range(1, t.size):
        error[k] = a * error[k - 1] + shocks[k]
    return t, scale * np.sum(error**2, axis=1)


def test_one_sample_per_block_lands_in_the_band_95_percent_of_the_time():
    rng = np.random.default_rng(1)
    inside = [consistency(np.arange(22) * 30.0 + 1.0, rng.chisquare(3, 22)).inside for _ in range(2000)]
    assert 0.93 <= np.mean(inside) <= 0.97


def test_an_honest_autocorrelated_filter_is_inside_the_block_band_but_not_the_epoch_band():
    rng = np.random.default_rng(2)
    block_inside, epoch_inside = [], []
    for _ in range(60):
        t, nees = correlated_nees(rng)
        result = consistency(t, nees)
        block_inside.append(result.inside)
        low, high = chi2_band(3, runs=t.size)
        epoch_inside.append(low <= nees.mean() <= high)
        assert result.blocks == 22
    assert np.mean(block_inside) >= 0.95
    assert np.mean(epoch_inside) <= 0.6


@pytest.mark.parametrize("scale, side", [(2.0, "above"), (0.4, "below")])
def test_an_over_or_under_confident_filter_falls_out_of_the_band_on_its_side(scale, side):
    rng = np.random.default_rng(3)
    results = [consistency(*correlated_nees(rng, scale)) for _ in range(20)]
    outside = [(r.block_anees > r.band[1]) if side == "above" else (r.block_anees < r.band[0]) for r in results]
    assert np.mean(outside) >= 0.9


def test_the_tail_shares_are_five_percent_each_for_an_honest_filter_and_grow_for_an_over_confident_one():
    rng = np.random.default_rng(4)
    honest = [consistency(*correlated_nees(rng)) for _ in range(30)]
    assert np.mean([r.share_above for r in honest]) == pytest.approx(0.05, abs=0.01)
    assert np.mean([r.share_below for r in honest]) == pytest.approx(0.05, abs=0.01)
    over = consistency(*correlated_nees(rng, 2.0))
    assert over.share_above > 0.2 and over.share_below < 0.02


def test_the_tail_points_are_chi_square_quantiles():
    from scipy.stats import chi2

    low, high = tail_points(3)
    assert low == pytest.approx(chi2.ppf(0.05, 3), rel=1e-9)
    assert high == pytest.approx(chi2.ppf(0.95, 3), rel=1e-9)


def test_the_running_tally_equals_the_arrays():
    rng = np.random.default_rng(5)
    t, nees = correlated_nees(rng)
    tally = ConsistencyTally()
    for a, b in zip(t.tolist(), nees.tolist()):
        tally.add(a, b)
    assert tally.result() == consistency(t, nees)


def test_a_short_last_block_and_non_finite_samples_are_left_out():
    t = np.concatenate([np.arange(0.0, 60.0, 0.1), [60.5]])
    nees = np.full(t.size, 3.0)
    nees[5] = np.nan
    result = consistency(t, np.where(t > 60.0, 1000.0, nees))
    assert result.blocks == 2 and result.block_anees == pytest.approx(3.0)
    assert result.samples == t.size - 1


def test_no_samples_give_no_verdict_and_mismatched_arrays_are_refused():
    empty = consistency(np.zeros(0), np.zeros(0))
    assert empty.blocks == 0 and not empty.inside and np.isnan(empty.block_anees)
    assert empty.as_dict()["block_anees"] is None
    with pytest.raises(ValueError, match="one length"):
        consistency(np.zeros(3), np.zeros(4))


def test_the_nis_book_counts_each_kind_apart_and_is_immutable():
    empty = NisBook()
    book = empty.add("landmark", 1.0, 2).add("landmark", 7.0, 2).add("gnss", 0.05, 2).add("robot", float("nan"), 2)
    assert empty.values == (0.0,) * len(empty.values)
    summary = nis_summary(book.values)
    assert set(summary) == {"landmark", "gnss"}
    assert summary["landmark"] == {"count": 2, "mean": 4.0, "share_above_95": 0.5, "share_below_05": 0.0}
    assert summary["gnss"]["share_below_05"] == 1.0
    assert nis_summary(()) == {} and nis_summary((1.0, 2.0)) == {}
    with pytest.raises(ValueError):
        book.add("no such kind", 1.0, 2)
    assert len(book.values) == 4 * len(NIS_KINDS)
