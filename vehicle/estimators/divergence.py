"""Divergence of a vehicle filter: when its state is no longer usable (non-finite, or a covariance no
longer positive definite), it restarts from the last good state with the covariance inflated
(``DIVERGENCE_INFLATION`` times, plus a floor on the pose and the GNSS error states).

``FullCheck`` checks all of P every cycle (a small filter); ``MapCheck`` checks a SLAM filter in O(n)
(the pose block positive definite, every variance positive and finite: a full check would cost
O(n^3) per cycle) and refreshes its fallback, an n x n copy, once per ``GOOD_PERIOD_US``. Pure."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from bus.notices import EstimatorReset, text_of
from bus.spd import spd, spd4
from vehicle.estimators.state import SEVERITY_WARNING, FilterState, Notice, frozen

DIVERGENCE_INFLATION = 10.0
DIVERGENCE_FLOOR = np.array([1.0, 1.0, 0.01, 1e-4])  # m^2, m^2, rad^2, (rad/s)^2
GOOD_PERIOD_US = 1_000_000


class FullCheck:
    def diverged(self, s: FilterState) -> bool:
        """Non-finite state or a covariance that is no longer (finite and) positive definite."""
        return not (math.isfinite(sum(s.x.tolist())) and spd(s.P))

    def remember(self, s: FilterState, t_us: int) -> None:
        """This cycle's state is the one to fall back to."""
        s.last_good = (frozen(s.x.copy()), frozen(s.P.copy()))

    def inflated(self, P: np.ndarray, gnss) -> np.ndarray:
        """The fallback covariance: inflated, with a floor on the pose and the GNSS error states
        (none on other added states)."""
        floor = np.zeros(len(P))
        floor[:4] = DIVERGENCE_FLOOR
        if gnss.error is not None:
            floor[4:6] = gnss.error.variance_m2
        return DIVERGENCE_INFLATION * P + np.diag(floor)


class MapCheck:
    def diverged(self, s: FilterState) -> bool:
        """Non-finite state, a pose block that is not positive definite, or a variance <= 0."""
        diagonal = np.diagonal(s.P)
        return not (
            math.isfinite(float(s.x.sum()))
            and spd4(s.P[:4, :4])
            and bool(np.all(diagonal > 0))
            and math.isfinite(float(diagonal.sum()))
        )

    def remember(self, s: FilterState, t_us: int) -> None:
        if t_us >= s.good_until_us:
            s.last_good = (frozen(s.x.copy()), frozen(s.P.copy()))
            s.good_until_us = t_us + GOOD_PERIOD_US

    def inflated(self, P: np.ndarray, gnss) -> np.ndarray:
        out = DIVERGENCE_INFLATION * P
        out[:4, :4] += np.diag(DIVERGENCE_FLOOR)
        return out


def fall_back(s: FilterState, inflated: Callable[[np.ndarray], np.ndarray], t_us: int) -> Notice:
    """A diverged state replaced by its fallback with the covariance ``inflated(P)``, or by nothing
    when it diverged before any good cycle (the filter then starts over); what to say about it."""
    if s.last_good is None:
        s.x, s.P = None, None
        return Notice(t_us, SEVERITY_WARNING, text_of(EstimatorReset("diverged before a good cycle")))
    x, P = s.last_good
    s.x, s.P = x.copy(), inflated(P)
    s.counters.resets += 1
    return Notice(t_us, SEVERITY_WARNING, text_of(EstimatorReset("non-finite or indefinite covariance")))
