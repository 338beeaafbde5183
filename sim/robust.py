"""Robust statistics the MRCLAM calibration shares: what lies within ``OUTLIER_SIGMAS`` robust sigmas
(1.4826 times the median absolute deviation) is data, what lies beyond is a gross misreading (a wrong
barcode, an occlusion, Vicon losing a robot), counted and left out. Pure."""

from __future__ import annotations

import numpy as np

OUTLIER_SIGMAS = 5.0
ROUNDS = 3  # refits of robust_fit, each without what the previous left beyond


def within(residual: np.ndarray, kept: np.ndarray) -> np.ndarray:
    """Rows (k,) whose residual is within OUTLIER_SIGMAS robust sigmas of the ``kept`` rows' spread."""
    spread = 1.4826 * np.median(np.abs(residual[kept]))
    return np.abs(residual) <= OUTLIER_SIGMAS * max(spread, 1e-9)


def inliers(residuals: np.ndarray) -> np.ndarray:
    """Mask (k,) of residuals within OUTLIER_SIGMAS robust sigmas of their median."""
    return within(residuals - np.median(residuals), np.ones(len(residuals), bool))


def robust_rms(residuals: np.ndarray) -> tuple[float, int]:
    """RMS of the residuals (k,) within OUTLIER_SIGMAS robust sigmas of their median, and how many lie beyond."""
    inside = inliers(residuals)
    return float(np.sqrt(np.mean(residuals[inside] ** 2))), int((~inside).sum())


def robust_fit(
    X: np.ndarray, y: np.ndarray, prior: tuple[np.ndarray, np.ndarray] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares coefficients (m,) of y (k,) on the columns of X (k, m), without the rows beyond
    OUTLIER_SIGMAS robust sigmas (misread barcodes): of y's median first, then of the previous fit,
    ROUNDS times; and the rows kept (k,) bool. With a ``prior`` (mean (m,), variance (m,)) the
    coefficients are its Gaussian posterior given the kept rows, their residual spread the noise."""
    keep = inliers(y)
    coef = np.zeros(X.shape[1])
    spread = 1.4826 * np.median(np.abs(y[keep] - np.median(y[keep])))
    for _ in range(ROUNDS):
        if prior is None:
            coef = np.linalg.lstsq(X[keep], y[keep], rcond=None)[0]
        else:
            mean, variance = prior
            noise = max(spread, 1e-9) ** 2
            information = X[keep].T @ X[keep] / noise + np.diag(1.0 / variance)
            coef = np.linalg.solve(information, X[keep].T @ y[keep] / noise + mean / variance)
        residual = y - X @ coef
        spread = 1.4826 * np.median(np.abs(residual[keep]))
        keep = within(residual, keep)
    return coef, keep
