"""Innovation-based adaptive estimation (IAE) of a measurement noise covariance (cooperative paper:
"IAE"; Mehra 1970, Mohamed and Schwarz 1999), pure.

Over the last N innovations v_k (m,) with predicted spreads H P H^T (m, m):
    R_hat = (1/N) sum v_k v_k^T - (1/N) sum H P_k H^T,
since E[v v^T] = H P H^T + R for a consistent filter. Until enough innovations are in, and wherever the
estimate is not positive definite enough, the sensor's nominal covariance bounds it. The estimate is
used from a quarter of a window on (a growing window until it is full): a filter that trusts a wrong
noise for a whole window builds up an error its covariance does not know about: in the nominal's
whitened frame the eigenvalues are clipped to [FLOOR, CEILING] (so R_hat stays between the datasheet
and a hundred times it).

IAE only learns a noise larger than the datasheet: the subtraction is right for a filter whose P is
its error's covariance, but a filter that fuses its neighbours by covariance intersection carries a
P that bounds its error from above (the ranging's predicted spread also holds the neighbour's CI
bound), so mean(v v^T) - mean(H P H^T) comes out below the sensor's real noise and a window that
reads "better than the datasheet" is that bound's slack, not the sensor (a floor below the
datasheet turned the cooperative experiment's IAE variant over-confident: docs/decisions/cooperative.md).
"""

from __future__ import annotations

import numpy as np

from bus.statistics import upper_quantile
from bus.topics import Topic

FLOOR, CEILING = 1.0, 100.0  # of the datasheet, in its whitened frame: learn only a noisier sensor
# the chi-square(2) 0.999999 quantile: innovations beyond it (spoofing, outliers) do not teach the estimate
GATE = upper_quantile(2, 1e-6)


class InnovationWindow:
    """The last ``window`` innovations of one sensor and the covariance they imply."""

    def __init__(self, window: int, dim: int = 2) -> None:
        self.window = window
        self._outer = np.zeros((window, dim, dim))  # v v^T - H P H^T per innovation
        self._count = 0

    def copy(self) -> InnovationWindow:
        twin = InnovationWindow.__new__(InnovationWindow)
        twin.window, twin._outer, twin._count = self.window, self._outer.copy(), self._count
        return twin

    @property
    def full(self) -> bool:
        return self._count >= self.window

    @property
    def usable(self) -> bool:
        return self._count >= max(5, self.window // 4)

    def add(self, innovation: np.ndarray, predicted_spread: np.ndarray) -> None:
        """One innovation v (m,) and its predicted spread H P H^T (m, m) (without R)."""
        self._outer[self._count % self.window] = np.outer(innovation, innovation) - predicted_spread
        self._count += 1

    def estimate(self) -> np.ndarray:
        """The raw R_hat (m, m) over what the window holds (not clipped; may be indefinite)."""
        return self._outer[: min(self._count, self.window)].mean(axis=0)

    def covariance(self, nominal: np.ndarray) -> np.ndarray:
        """R_hat (m, m), clipped against ``nominal`` (m, m); ``nominal`` itself until a quarter window is in."""
        if not self.usable:
            return nominal
        estimate = self.estimate()
        L = np.linalg.cholesky(nominal)
        whitened = np.linalg.solve(L, np.linalg.solve(L, estimate).T)  # L^-1 R_hat L^-T
        values, vectors = np.linalg.eigh(0.5 * (whitened + whitened.T))
        clipped = (vectors * np.clip(values, FLOOR, CEILING)) @ vectors.T
        return L @ clipped @ L.T


class NoiseAdaptation:
    """IAE of one vehicle's GNSS and ranging noise: a window per sensor. ``adapt`` learns from one
    innovation (unless it is beyond ``GATE``: spoofing, outliers) and returns the noise to fuse it with."""

    SENSORS = (Topic.GNSS, Topic.RANGING)

    def __init__(self, window: int) -> None:
        self.windows = {sensor: InnovationWindow(window) for sensor in self.SENSORS}

    def copy(self) -> NoiseAdaptation:
        twin = NoiseAdaptation.__new__(NoiseAdaptation)
        twin.windows = {sensor: window.copy() for sensor, window in self.windows.items()}
        return twin

    def adapt(self, sensor: str, innovation: np.ndarray, spread: np.ndarray, nominal: np.ndarray) -> np.ndarray:
        """The covariance (m, m) to fuse this ``sensor``'s measurement with, after learning from its
        innovation (m,) and predicted spread without noise (m, m); ``nominal`` is the datasheet's."""
        window = self.windows[sensor]
        if innovation @ np.linalg.solve(spread + window.covariance(nominal), innovation) <= GATE:
            window.add(innovation, spread)
        return window.covariance(nominal)

    def estimates(self) -> dict[str, np.ndarray]:
        """Raw R_hat (m, m) of every sensor whose window is full."""
        return {sensor: window.estimate() for sensor, window in self.windows.items() if window.full}
