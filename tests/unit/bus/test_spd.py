"""Every form of the one SPD check (bus.spd) decides as numpy's Cholesky does, on random symmetric
matrices near the boundary (the lowest eigenvalue just above or just below zero) and on non-finite ones."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bus.spd import all_spd2, all_spd3, spd, spd2_row, spd4, spd_values


def _cholesky(M: np.ndarray) -> bool:
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        return False
    return bool(np.isfinite(M).all())


@st.composite
def symmetric(draw, n: int) -> np.ndarray:
    seed = draw(st.integers(0, 2**32 - 1))
    lowest = draw(st.sampled_from([-1.0, -1e-3, 1e-3, 1.0]))  # at exactly 0 rounding decides
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    values = np.concatenate([[lowest], rng.uniform(0.1, 10.0, n - 1)])
    M = Q @ np.diag(values) @ Q.T
    return 0.5 * (M + M.T)


@settings(max_examples=200)
@given(st.integers(1, 6).flatmap(symmetric))
def test_every_form_decides_as_cholesky(M):
    expected = _cholesky(M)
    n = len(M)
    assert spd(M) is expected and spd_values(M.ravel().tolist(), n) is expected
    if n == 4:
        assert spd4(M) is expected
    if n == 2:
        assert spd2_row(*M.ravel().tolist()) is expected and all_spd2(M.reshape(1, 4)) is expected
    if n == 3:
        assert all_spd3(M.reshape(1, 9)) is expected


def test_non_finite_or_asymmetric_matrices_are_not_spd():
    bad = np.eye(4)
    bad[1, 1] = np.nan
    assert not spd(bad) and not spd4(bad) and not spd_values(bad.ravel().tolist(), 4)
    assert not spd2_row(1.0, 0.5, 0.4, 1.0) and not all_spd2(np.array([[1.0, 0.5, 0.4, 1.0]]))
    assert not all_spd3(np.array([[1.0, 0.5, 0, 0.4, 1.0, 0, 0, 0, 1.0]]))
    assert not spd(np.full((5, 5), np.inf))
