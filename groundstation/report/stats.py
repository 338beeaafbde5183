"""Time-binned swarm statistics and per-vehicle figures of merit for the report (pure numpy)."""

from __future__ import annotations

from typing import Any

import numpy as np

from bus import statistics
from groundstation.report.rundata import RunData


def binned_nees(
    t_s: np.ndarray, vehicle: np.ndarray, nees: np.ndarray, bin_s: float, dof: int = statistics.POSE_NEES_DOF
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Swarm-average NEES per time bin with its two-sided 95% chi-square band.

    Samples of one vehicle are correlated in time, so each bin takes one sample per vehicle (its first
    in the bin) and averages across the k vehicles, which are independent like Monte Carlo runs:
    k * mean NEES ~ chi2(k * dof) (Bar-Shalom, Li, Kirubarajan 2001, sec. 5.4.2).
    Inputs (N,) each; returns (bin centres s, mean NEES, lower bound, upper bound), each (B,).
    """
    index = np.floor(t_s / bin_s).astype(int)
    order = np.lexsort((t_s, vehicle, index))
    pair = np.stack([index[order], vehicle[order]], axis=1)
    first = order[np.r_[True, np.any(pair[1:] != pair[:-1], axis=1)]]
    count = np.bincount(index[first])
    total = np.bincount(index[first], weights=nees[first])
    used = count > 0
    k = count[used]
    lower, upper = statistics.chi2_bands(dof, k)
    return (np.flatnonzero(used) + 0.5) * bin_s, total[used] / k, lower, upper


def vehicle_table(data: RunData) -> list[dict[str, Any]]:
    """One row per vehicle: RMSE, max error, ANEES and counters, from summary.json where it exists and
    from metrics.csv otherwise (a killed run has no summary)."""
    from_summary = (data.summary or {}).get("vehicles", {})
    timing = (data.timing or {}).get("vehicles", {})
    rows = []
    for vid in data.vehicles:
        s, t = from_summary.get(str(vid), {}), timing.get(str(vid), {})
        m = data.rows_of(vid)
        err = m.get("err_pos_m", np.empty(0))
        rows.append(
            {
                "vehicle": vid,
                "samples": s.get("samples", len(err)),
                "rmse_m": s.get("rmse_m", float(np.sqrt(np.mean(err**2))) if len(err) else None),
                "max_error_m": s.get("max_error_m", float(err.max()) if len(err) else None),
                "anees": s.get("anees", float(np.mean(m["nees"])) if len(err) else None),
                "overruns": t.get("overruns", s.get("overruns")),
                "gnss_rejected": s.get("gnss_rejected"),
                "dropped_stale": s.get("dropped_stale"),
                "mavlink_rejected": s.get("mavlink_rejected"),
                "decode_errors": s.get("decode_errors"),
                "resets": int(m["reset_counter"].max()) if len(err) and "reset_counter" in m else None,
            }
        )
    return rows


def swarm_rmse(data: RunData) -> float | None:
    if data.summary and data.summary.get("swarm", {}).get("rmse_m") is not None:
        return data.summary["swarm"]["rmse_m"]
    err = data.metrics.get("err_pos_m")
    return float(np.sqrt(np.mean(err**2))) if err is not None and len(err) else None


def covariance_ellipse(cov_xy: np.ndarray, n_sigma: float = 3.0, points: int = 48) -> np.ndarray:
    """(points, 2) outline offsets (m) of the n-sigma ellipse of a 2x2 position covariance (m^2)."""
    values, vectors = np.linalg.eigh(cov_xy)
    angle = np.linspace(0.0, 2.0 * np.pi, points)
    circle = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    return n_sigma * (circle * np.sqrt(np.clip(values, 0.0, None))) @ vectors.T
