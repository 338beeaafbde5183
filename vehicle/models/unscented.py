"""The unscented transform for the unicycle state (cooperative-localization paper: UKF with sigma
points and lambda scaling), angle-aware: the heading's mean is circular and residuals are wrapped.
Pure.

Sigma points (n = len(x)): chi_0 = x, chi_{+-i} = x +- sqrt(n + lambda) L_i with L L^T = P and
lambda = alpha^2 (n + kappa) - n; weights W_m0 = lambda / (n + lambda), W_c0 = W_m0 + 1 - alpha^2 +
beta, W_i = 1 / (2 (n + lambda)). The defaults (alpha = 1, beta = 2, kappa = 0) keep every weight of
the mean non-negative, so the transformed covariance stays positive semi-definite.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bus.angles import wrap_angle

HEADING = 2  # index of the angle in the unicycle state


@dataclass(frozen=True)
class Scaling:
    alpha: float = 1.0
    beta: float = 2.0
    kappa: float = 0.0

    def weights(self, n: int) -> tuple[float, np.ndarray, np.ndarray]:
        """(lambda, W_m (2n+1,), W_c (2n+1,))."""
        lam = self.alpha**2 * (n + self.kappa) - n
        wm = np.full(2 * n + 1, 0.5 / (n + lam))
        wc = wm.copy()
        wm[0] = lam / (n + lam)
        wc[0] = wm[0] + 1.0 - self.alpha**2 + self.beta
        return lam, wm, wc


def sigma_points(x: np.ndarray, P: np.ndarray, lam: float) -> np.ndarray:
    """(2n+1, n) sigma points of mean x (n,) and covariance P (n, n)."""
    n = len(x)
    L = np.linalg.cholesky((n + lam) * P)
    return np.vstack([x, x + L.T, x - L.T])


def state_mean(chi: np.ndarray, wm: np.ndarray) -> np.ndarray:
    """Weighted mean of sigma points (m, n) with a circular mean for the heading."""
    mean = wm @ chi
    mean[HEADING] = np.arctan2(wm @ np.sin(chi[:, HEADING]), wm @ np.cos(chi[:, HEADING]))
    return mean


def state_residuals(chi: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """chi - mean (m, n) with the heading difference wrapped to (-pi, pi]."""
    d = chi - mean
    d[:, HEADING] = (d[:, HEADING] + np.pi) % (2.0 * np.pi) - np.pi
    return d


def propagate(
    x: np.ndarray, P: np.ndarray, f: Callable[[np.ndarray], np.ndarray], Q: np.ndarray, scaling: Scaling = Scaling()
) -> tuple[np.ndarray, np.ndarray]:
    """Unscented prediction: mean (n,) and covariance (n, n) of f(x) plus additive noise Q (n, n)."""
    lam, wm, wc = scaling.weights(len(x))
    chi = np.array([f(point) for point in sigma_points(x, P, lam)])
    mean = state_mean(chi, wm)
    d = state_residuals(chi, mean)
    P_new = (d * wc[:, None]).T @ d + Q
    return mean, 0.5 * (P_new + P_new.T)


def measure(
    x: np.ndarray,
    P: np.ndarray,
    h: Callable[[np.ndarray], np.ndarray],
    angle_rows: tuple[int, ...],
    scaling: Scaling = Scaling(),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Unscented measurement prediction: z_hat (m,), P_zz (m, m) without measurement noise and the
    cross-covariance P_xz (n, m); ``angle_rows`` are the measurement's angles (circular mean, wrapped
    residuals)."""
    lam, wm, wc = scaling.weights(len(x))
    chi = sigma_points(x, P, lam)
    Z = np.array([h(point) for point in chi])
    z_hat = wm @ Z
    for row in angle_rows:
        z_hat[row] = np.arctan2(wm @ np.sin(Z[:, row]), wm @ np.cos(Z[:, row]))
    dz = Z - z_hat
    for row in angle_rows:
        dz[:, row] = (dz[:, row] + np.pi) % (2.0 * np.pi) - np.pi
    dx = state_residuals(chi, x)
    return z_hat, (dz * wc[:, None]).T @ dz, (dx * wc[:, None]).T @ dz


def wrap_heading(x: np.ndarray) -> np.ndarray:
    x = x.copy()
    x[HEADING] = wrap_angle(float(x[HEADING]))
    return x
