"""GNSS health: is the receiver jammed or spoofed? (pure, one instance per vehicle)

Two tests per fix, on the innovation y = fix - H x with covariance S = H P H^T + R, whitened as
w = L^-1 y with L L^T = S (so w ~ N(0, I) for a consistent filter and honest GNSS):
- the fix test ratio |w|^2 / chi2_2(p), PX4-style: above 1 the fix is rejected;
- the innovation-mean test ratio N |mean(w)|^2 / chi2_2(p) over the last N fused fixes: a slowly
  growing spoofing offset pulls the filter along, so each fix passes its own gate, but the
  innovations stop averaging to zero.
Sustained failure (either test failing for ``unhealthy_after_s``) or no fix for ``fix_timeout_s``
marks GNSS unhealthy; it is trusted again after ``recover_after_s`` of fixes consistent with the
filter. A filter that drifted while GNSS was out (or was dragged by a spoofer before detection) may
never see consistent fixes again, so there is a second way back, a position reset (as PX4 does): the
last ``reset_window`` fixes agree with each other (a straight-line fit in time of their innovations
leaves residuals consistent with R), the jump is plausible for the filter's own uncertainty inflated
to 3 sigma (so a spoofer far away cannot capture the filter), and the position jumps to the fixes.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from bus.statistics import gate_threshold, upper_quantile
from vehicle.estimators.shallow import shallow_copy


@dataclass(frozen=True)
class GnssHealthSpec:
    unhealthy_after_s: float = 1.0
    fix_timeout_s: float = 1.5
    recover_after_s: float = 5.0
    mean_window: int = 25  # fixes (5 s at 5 Hz)
    gate_probability: float = 0.9995
    mean_gate_probability: float = 0.9999
    reset_window: int = 25  # fixes (5 s at 5 Hz)
    reset_probability: float = 0.999
    reset_sigma_inflation: float = 3.0


@dataclass(frozen=True)
class FixVerdict:
    fuse: bool
    test_ratio: float  # |w|^2 / gate
    mean_test_ratio: float  # N |mean w|^2 / gate over the window (0 until the window is full)
    reset_offset_m: np.ndarray | None = None  # (2,) position jump when GNSS is trusted again by reset
    reset_variance_m2: float = 0.0  # per-axis variance of that offset


@dataclass
class GnssHealth:
    spec: GnssHealthSpec = field(default_factory=GnssHealthSpec)
    healthy: bool = True
    reason: str = ""
    last_fix_us: int | None = None
    _failing_since_us: int | None = None
    _consistent_since_us: int | None = None
    _window: deque = field(default_factory=deque)
    _outage: deque = field(default_factory=deque)  # (innovation (2,), R (2, 2)) while unhealthy
    transitions: list[tuple[int, bool, str]] = field(default_factory=list)  # (stamp, healthy, reason) to report
    last_test_ratio: float = 0.0
    last_mean_test_ratio: float = 0.0

    def copy(self) -> GnssHealth:
        """An independent copy (the windows are copied; their entries are never changed in place)."""
        twin = shallow_copy(self)
        twin._window, twin._outage, twin.transitions = deque(self._window), deque(self._outage), list(self.transitions)
        return twin

    def check(
        self,
        stamp_us: int,
        innovation: np.ndarray,
        S: np.ndarray,
        R: np.ndarray,
        may_reset: Callable[[np.ndarray], bool] | None = None,
    ) -> FixVerdict:
        """Judge one fix: innovation (2,), its covariance S (2, 2) and the fix's own R (2, 2) (m, m^2).
        ``may_reset(offset)``: whether a position reset by that offset (2,) is allowed by what else
        the vehicle knows (its neighbours); refused, GNSS stays unhealthy."""
        self.last_fix_us = stamp_us
        w = _whitened(innovation, S)
        ratio = (w[0] * w[0] + w[1] * w[1]) / gate_threshold(2, self.spec.gate_probability)
        mean_ratio = self._mean_ratio(w) if self.healthy and ratio <= 1.0 else 0.0
        consistent = ratio <= 1.0 and mean_ratio <= 1.0
        self.last_test_ratio, self.last_mean_test_ratio = ratio, mean_ratio
        if self.healthy:
            self._judge_healthy(
                stamp_us, consistent, "spoofing suspected" if mean_ratio > 1.0 else "fixes fail the gate"
            )
        else:
            self._judge_unhealthy(stamp_us, ratio <= 1.0)
            if not self.healthy:
                offset = self._self_consistent_offset(stamp_us, innovation, R)
                plausible = offset is not None and self._plausible_jump(offset, S - R, R)
                if plausible and (may_reset is None or may_reset(offset)):
                    self._set(stamp_us, True, "reset to consistent fixes")
                    return FixVerdict(
                        False, ratio, mean_ratio, offset, 4.0 * float(np.mean(np.diag(R))) / self.spec.reset_window
                    )
        return FixVerdict(self.healthy and consistent, ratio, mean_ratio)

    def _plausible_jump(self, offset: np.ndarray, P_pos: np.ndarray, R: np.ndarray) -> bool:
        """A reset may move the position by what the filter's own uncertainty, inflated to 3x in sigma,
        allows: a spoofer that dragged fixes far away does not get to drag the filter with it."""
        spread = self.spec.reset_sigma_inflation**2 * P_pos + R / self.spec.reset_window
        return float(offset @ np.linalg.solve(spread, offset)) <= gate_threshold(2, self.spec.gate_probability)

    def _self_consistent_offset(self, stamp_us: int, innovation: np.ndarray, R: np.ndarray) -> np.ndarray | None:
        """The current offset between fixes and the dead-reckoned filter if the last ``reset_window``
        fixes agree with each other, else None.

        Dead reckoning drifts, so the innovations are fitted with a straight line in time per axis,
        y_k = a + b (t_k - t_mean); the fixes agree when the fit residuals are consistent with R
        (sum of whitened squares ~ chi2(2 (n - 2))). The offset is the line at the latest fix.
        """
        self._outage.append((stamp_us * 1e-6, innovation, R))
        n = self.spec.reset_window
        if len(self._outage) > n:
            self._outage.popleft()
        if len(self._outage) < n:
            return None
        t = np.array([o[0] for o in self._outage])
        y = np.array([o[1] for o in self._outage])
        design = np.stack([np.ones(n), t - t.mean()], axis=1)
        coef, *_ = np.linalg.lstsq(design, y, rcond=None)
        L = np.linalg.cholesky(np.mean([o[2] for o in self._outage], axis=0))
        residual = np.linalg.solve(L, (y - design @ coef).T)
        if float(np.sum(residual**2)) > upper_quantile(2 * (n - 2), 1.0 - self.spec.reset_probability):
            return None
        return coef[0] + coef[1] * (t[-1] - t.mean())

    def tick(self, stamp_us: int) -> None:
        """Loss of fix: no fix for ``fix_timeout_s`` (jamming) makes GNSS unhealthy."""
        timeout_us = self.spec.fix_timeout_s * 1e6
        if self.healthy and self.last_fix_us is not None and stamp_us - self.last_fix_us > timeout_us:
            self._set(stamp_us, False, "no fix, jamming suspected")

    def _mean_ratio(self, w: tuple[float, float]) -> float:
        self._window.append(w)
        if len(self._window) > self.spec.mean_window:
            self._window.popleft()
        n = len(self._window)
        if n < self.spec.mean_window:
            return 0.0
        mean0, mean1 = sum(v[0] for v in self._window) / n, sum(v[1] for v in self._window) / n
        return n * (mean0 * mean0 + mean1 * mean1) / gate_threshold(2, self.spec.mean_gate_probability)

    def _judge_healthy(self, stamp_us: int, consistent: bool, reason: str) -> None:
        if consistent:
            self._failing_since_us = None
            return
        if self._failing_since_us is None:
            self._failing_since_us = stamp_us
        if stamp_us - self._failing_since_us >= self.spec.unhealthy_after_s * 1e6:
            self._set(stamp_us, False, reason)

    def _judge_unhealthy(self, stamp_us: int, consistent: bool) -> None:
        if not consistent:
            self._consistent_since_us = None
            return
        if self._consistent_since_us is None:
            self._consistent_since_us = stamp_us
        if stamp_us - self._consistent_since_us >= self.spec.recover_after_s * 1e6:
            self._set(stamp_us, True, "consistent again")

    def _set(self, stamp_us: int, healthy: bool, reason: str) -> None:
        self.healthy, self.reason = healthy, reason
        self._failing_since_us = self._consistent_since_us = None
        self._window.clear()
        self._outage.clear()
        self.transitions.append((stamp_us, healthy, reason))


def _whitened(innovation: np.ndarray, S: np.ndarray) -> tuple[float, float]:
    """L^-1 y for the Cholesky factor L of the 2 x 2 covariance S (a fix's innovation whitened), on
    floats; a covariance that is not positive definite raises ValueError."""
    (s00, s01), (_, s11) = S.tolist()
    y0, y1 = innovation.tolist()
    l00 = math.sqrt(s00)
    l10 = s01 / l00
    l11 = math.sqrt(s11 - l10 * l10)
    w0 = y0 / l00
    return w0, (y1 - l10 * w0) / l11
