"""A neighbour's fix window answers every window question as the one-pass definition does."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vehicle.trust.neighbour_fixes import Fix, FixWindow, window_stats

STEPS_US = (0, 50_000, 100_000, 200_000)


def random_fixes(rng: np.random.Generator, n: int) -> list[Fix]:
    """``n`` fixes in stamp order (ties included), a few with a non-finite innovation, a fifth gated out."""
    stamps = np.cumsum(rng.choice(STEPS_US, size=n))
    whitened = rng.normal(0.0, 2.0, size=(n, 2))
    whitened[rng.random(n) < 0.03] = math.inf
    gated = rng.random(n) < 0.2
    return [Fix(int(t), float(w @ w), (float(w[0]), float(w[1])), bool(g)) for t, w, g in zip(stamps, whitened, gated)]


def assert_same(expected, got) -> None:
    assert (got.fixes, got.gated_out) == (expected.fixes, expected.gated_out)
    for a, b in ((expected.mean_nis, got.mean_nis), (expected.bias, got.bias)):
        assert b == a if math.isinf(a) else b == pytest.approx(a, rel=1e-9, abs=1e-9)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_every_window_as_the_definition_while_fixes_come_and_go(seed: int) -> None:
    rng = np.random.default_rng(seed)
    window, kept = FixWindow(), []
    for fix in random_fixes(rng, 600):
        window.append(fix)
        kept.append(fix)
        while kept[0].stamp_us <= fix.stamp_us - 20_000_000:  # the long window's horizon, as the monitor keeps it
            kept.pop(0)
            window.popleft()
        if rng.random() < 0.1:  # a checkpoint's copy carries on as the original would
            window = window.copy()
        assert list(window) == kept and window[-1] is kept[-1] and window.latest(8) == kept[-8:]
        for since in (fix.stamp_us - 5_000_000, fix.stamp_us - 20_000_000, int(rng.integers(-1, fix.stamp_us + 1))):
            for decorrelation_s in (0.0, 1.0):
                assert_same(window_stats(kept, since, decorrelation_s), window.stats(since, decorrelation_s))


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 3_000_000), min_size=1, max_size=40), st.integers(0, 40), st.integers(-1, 4_000_000))
def test_a_fix_out_of_stamp_order_is_answered_by_the_definition(stamps, pops, since) -> None:
    fixes = [Fix(t, 1.0, (0.5, -0.5 if i % 3 else 9.0), i % 4 == 0) for i, t in enumerate(stamps)]
    window = FixWindow()
    for fix in fixes:
        window.append(fix)
    pops = min(pops, len(fixes) - 1)
    for _ in range(pops):
        window.popleft()
    assert len(window) == len(fixes) - pops
    assert_same(window_stats(fixes[pops:], since, 1.0), window.stats(since, 1.0))


def test_an_empty_window_says_nothing_and_refuses_to_pop() -> None:
    window = FixWindow()
    assert not window and window.stats(0).fixes == 0 and math.isinf(window.stats(0).mean_nis)
    with pytest.raises(IndexError):
        window.popleft()
    with pytest.raises(IndexError):
        window[-1]
