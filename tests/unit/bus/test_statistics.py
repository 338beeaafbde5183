"""The vehicle's chi-square quantiles (no scipy in a vehicle process) agree with scipy's."""

import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.special import chdtrc, chdtri

from bus.statistics import survival, upper_quantile


@pytest.mark.parametrize("dof", [1, 2, 3, 46, 200])
@pytest.mark.parametrize("tail", [0.9, 0.05, 1e-6, 1e-9])
def test_quantiles_match_scipy(dof, tail):
    assert upper_quantile(dof, tail) == pytest.approx(float(chdtri(dof, tail)), rel=1e-10)


@given(st.integers(1, 200), st.floats(0.0, 500.0))
def test_the_survival_function_matches_scipy(dof, x):
    assert survival(dof, x) == pytest.approx(float(chdtrc(dof, x)), rel=1e-9, abs=1e-300)


@pytest.mark.parametrize("dof, tail", [(0, 0.05), (-2, 0.05), (201, 0.05), (2, 0.0), (2, 1.0), (2, float("nan"))])
def test_impossible_dofs_and_tails_are_refused(dof, tail):
    with pytest.raises(ValueError):
        upper_quantile(dof, tail)


@pytest.mark.parametrize("dof, runs", [(3, 1), (3, 10), (2, 50), (3, 66), (3, 67), (3, 500)])
def test_the_nees_band_matches_scipy_with_and_without_it(dof, runs):
    from scipy.stats import chi2

    from bus.statistics import chi2_band

    low, high = chi2_band(dof, runs=runs)
    assert low == pytest.approx(chi2.ppf(0.025, dof * runs) / runs, rel=1e-12)
    assert high == pytest.approx(chi2.ppf(0.975, dof * runs) / runs, rel=1e-12)
