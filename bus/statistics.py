"""The statistics every part of swarmloc shares, computed once here: chi-square quantiles for the
vehicles' gates, the two-sided NEES bands for scoring and experiments, NEES itself, and time bins.

Gates (``upper_quantile``, ``gate_threshold``) need no scipy: importing ``scipy.special`` cost every
vehicle process about 0.25 s of CPU at start, for a handful of numbers.

The survival function of chi-square with k degrees of freedom has a closed form built up two degrees
at a time, Q_{k+2}(x) = Q_k(x) + (x / 2)^(k / 2) exp(-x / 2) / Gamma(k / 2 + 1), from Q_2(x) = exp(-x / 2)
and Q_1(x) = erfc(sqrt(x / 2)) (Abramowitz and Stegun 26.4.4-5); the quantile follows by bisection to
the last bits of a float. Meant for the gates' few degrees of freedom (at most MAX_DOF). Pure.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

from bus.angles import wrap_angle

MAX_ITERATIONS = 200
MAX_DOF = 200
POSE_NEES_DOF = 3  # NEES over a pose [x, y, yaw]


def survival(dof: int, x: float) -> float:
    """P(chi-square with ``dof`` (1..MAX_DOF) degrees of freedom > ``x``)."""
    _check_dof(dof)
    if x <= 0.0:
        return 1.0
    half = 0.5 * x
    if dof % 2:  # Q_1, and t_1 = (x/2)^(1/2) exp(-x/2) / Gamma(3/2)
        k, total, term = 1, math.erfc(math.sqrt(half)), math.sqrt(half) * math.exp(-half) / math.gamma(1.5)
    else:  # Q_2, and t_2 = (x/2) exp(-x/2) / Gamma(2)
        k, total, term = 2, math.exp(-half), half * math.exp(-half)
    while k < dof:  # Q_{k+2} = Q_k + t_k, t_{k+2} = t_k (x/2) / (k/2 + 1)
        total += term
        term *= half / (0.5 * k + 1.0)
        k += 2
    return total


@cache
def upper_quantile(dof: int, tail: float) -> float:
    """x with P(chi-square with ``dof`` degrees of freedom > x) = ``tail`` (0 < tail < 1): scipy's
    ``chdtri(dof, tail)``, ``chi2.isf(tail, dof)``."""
    _check_dof(dof)
    if not 0.0 < tail < 1.0:
        raise ValueError(f"tail probability {tail!r} is not inside (0, 1)")
    low, high = 0.0, float(dof)
    while survival(dof, high) > tail:  # the survival function falls: bracket the quantile
        low, high = high, 2.0 * high
    for _ in range(MAX_ITERATIONS):
        middle = 0.5 * (low + high)
        if middle in (low, high):
            break
        low, high = (middle, high) if survival(dof, middle) > tail else (low, middle)
    return 0.5 * (low + high)


def _check_dof(dof: int) -> None:
    if not 1 <= dof <= MAX_DOF:
        raise ValueError(f"{dof} degrees of freedom: expected 1 to {MAX_DOF}")


def gate_threshold(dof: int, probability: float) -> float:
    """The chi-square gate that passes ``probability`` of consistent innovations of ``dof``
    dimensions: NIS above it is rejected (PX4-style test ratio NIS / gate > 1)."""
    return upper_quantile(dof, 1.0 - probability)


def chi2_band(dof: int, *, runs: int = 1, probability: float = 0.95) -> tuple[float, float]:
    """Two-sided ``probability`` band of the average of ``runs`` independent NEES (or NIS) samples of
    ``dof`` dimensions each: runs * average ~ chi2(runs * dof) (Bar-Shalom, Li, Kirubarajan 2001,
    sec. 5.4.2). ``runs`` = 1 is the band of one sample. Up to MAX_DOF degrees of freedom in all from
    the closed form (no scipy: the ground station starts without it); beyond, scipy's."""
    tail, total = _tail(probability), dof * runs
    if total <= MAX_DOF:
        return upper_quantile(total, 1.0 - tail) / runs, upper_quantile(total, tail) / runs
    from scipy.stats import chi2

    low, high = chi2.ppf([tail, 1.0 - tail], total) / runs
    return float(low), float(high)


def chi2_bands(dof: int, runs: np.ndarray, probability: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """:func:`chi2_band` for an array of run counts (k,): lower (k,) and upper (k,) bounds."""
    from scipy.stats import chi2

    runs = np.asarray(runs)
    tail = _tail(probability)
    return chi2.ppf(tail, dof * runs) / runs, chi2.ppf(1.0 - tail, dof * runs) / runs


def _tail(probability: float) -> float:
    """The one-sided tail of a two-sided ``probability`` band, as the decimal it is (0.95: 0.025,
    not 0.025000000000000022)."""
    if not 0.0 < probability < 1.0:
        raise ValueError(f"band probability {probability!r} is not inside (0, 1)")
    return round(0.5 * (1.0 - probability), 12)


def pose_error(pose: np.ndarray, truth_pose: np.ndarray) -> np.ndarray:
    """Error (3,) of a pose [x m, y m, yaw rad] (3,) against the truth (3,), yaw wrapped."""
    return np.array([pose[0] - truth_pose[0], pose[1] - truth_pose[1], wrap_angle(pose[2] - truth_pose[2])])


def published_pose_cov(pose_cov: np.ndarray, unmodelled_sigma_m: float) -> np.ndarray:
    """A filter's pose covariance (3, 3) [m, m, rad] as it is published: with ``unmodelled_sigma_m``^2
    added to each position variance (sensors.unmodelled_sigma_m: what no sighting can see)."""
    if not unmodelled_sigma_m:
        return pose_cov
    out = pose_cov.copy()
    out[0, 0] += unmodelled_sigma_m**2
    out[1, 1] += unmodelled_sigma_m**2
    return out


def nees(error: np.ndarray, covariance: np.ndarray) -> float:
    """Normalized estimation error squared e^T P^-1 e of an error (k,) under its covariance (k, k)."""
    return float(error @ np.linalg.solve(covariance, error))


def time_bins(t_s: np.ndarray, bin_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Bin index (N,) of each time (N,) s in bins of ``bin_s``, and the used bins' centres (B,) s."""
    index = np.floor(np.asarray(t_s) / bin_s).astype(int)
    used = np.bincount(index) > 0
    return index, (np.flatnonzero(used) + 0.5) * bin_s


def binned_mean(t_s: np.ndarray, values: np.ndarray, bin_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres (B,) s, mean of ``values`` (N,) per bin (B,)), empty bins left out."""
    index, centres = time_bins(t_s, bin_s)
    count = np.bincount(index)
    total = np.bincount(index, weights=values)
    used = count > 0
    return centres, total[used] / count[used]


def binned_rms(t_s: np.ndarray, values: np.ndarray, bin_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres (B,) s, root mean square of ``values`` (N,) per bin (B,)), empty bins left out."""
    centres, mean_square = binned_mean(t_s, np.asarray(values) ** 2, bin_s)
    return centres, np.sqrt(mean_square)


def interval(values: list[float | None]) -> tuple[float, float, int]:
    """(mean, half width of the 95 % confidence interval, n) of independent samples (Student's t:
    mean +- t(0.975, n - 1) s / sqrt(n); NaN width when n < 2; None and non-finite values left out)."""
    from scipy.stats import t

    data = np.array([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if data.size == 0:
        return math.nan, math.nan, 0
    if data.size < 2:
        return float(data.mean()), math.nan, 1
    half = float(t.ppf(0.975, data.size - 1) * data.std(ddof=1) / math.sqrt(data.size))
    return float(data.mean()), half, int(data.size)
