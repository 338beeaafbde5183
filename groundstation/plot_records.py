"""The JSON channels a Foxglove or Lichtblick plot reads (groundstation.recording): each one's JSON
schema and the record written for it. The schemas use only what both viewers parse (Lichtblick's
packages/mcap-support parseJsonSchema: an object of boolean, string, number, integer, object and
array properties, one type each): a value that is missing is a field left out, never a null. Pure."""

from __future__ import annotations

import math
from typing import Any

from bus.statistics import chi2_band
from groundstation.scoring import Score


def _schema(title: str, **properties: dict) -> dict[str, Any]:
    return {"title": title, "type": "object", "properties": properties}


NUMBER, INTEGER = {"type": "number"}, {"type": "integer"}
METRICS_SCHEMA = _schema(
    "swarmloc.Metrics",
    t_s={"type": "number", "description": "sim time (s)"},
    vehicle=INTEGER,
    err_pos_m={"type": "number", "description": "horizontal position error (m)"},
    nees={"type": "number", "description": "pose NEES, 3 dof (left out when it is not finite)"},
    sigma_x_m=NUMBER,
    sigma_y_m=NUMBER,
    nees_band_low={"type": "number", "description": "two-sided 95 % band of one 3-dof NEES"},
    nees_band_high=NUMBER,
    err_alt_m={"type": "number", "description": "height error, estimate - truth (m; a vehicle that estimates it)"},
    sigma_alt_m={"type": "number", "description": "its 1-sigma (m)"},
)
HEALTH_SCHEMA = _schema(
    "swarmloc.GnssHealth",
    t_s={"type": "number", "description": "the vehicle's time (s)"},
    vehicle=INTEGER,
    gnss_test_ratio={"type": "number", "description": "GNSS innovation test ratio (> 1 rejects)"},
    gnss_glitch={"type": "boolean", "description": "the vehicle distrusts its receiver"},
    horizontal_accuracy_m={"type": "number", "description": "1-sigma horizontal accuracy (m)"},
)
SWARM_SCHEMA = _schema(
    "swarmloc.SwarmError",
    t_s={"type": "number", "description": "sim time (s)"},
    rms_error_m={"type": "number", "description": "RMS position error of the vehicles scored then (m)"},
    max_error_m={"type": "number", "description": "the largest position error of the vehicles scored then (m)"},
    mean_nees={"type": "number", "description": "mean pose NEES (3 dof) of the vehicles scored then"},
    vehicles=INTEGER,
)
LOOP_SCHEMA = _schema(
    "swarmloc.LoopStatus",
    t_s={"type": "number", "description": "sim time of the report (s)"},
    vehicle=INTEGER,
    cycles=INTEGER,
    overruns={"type": "integer", "description": "estimator cycles that overran their period"},
    cycle_p99_us=NUMBER,
    jitter_p99_us=NUMBER,
    v2v_fused=INTEGER,
    v2v_missing=INTEGER,
)


def metrics_record(s: Score, nees_band: tuple[float, float]) -> dict[str, Any]:
    """One metrics message of a score (the vehicle's /vehicle/<id>/metrics); ``nees_band``:
    chi2_band(3) (the plots draw it). A NEES that is not finite is left out, and so is the height's
    error and sigma where the vehicle does not estimate its height."""
    record = {
        "t_s": s.stamp_us * 1e-6,
        "vehicle": s.vehicle_id,
        "err_pos_m": s.position_error_m,
        "sigma_x_m": float(s.sigma[0]),
        "sigma_y_m": float(s.sigma[1]),
        "nees_band_low": nees_band[0],
        "nees_band_high": nees_band[1],
    }
    if math.isfinite(s.nees):
        record["nees"] = s.nees
    if math.isfinite(s.altitude_error_m):
        record["err_alt_m"] = s.altitude_error_m
        record["sigma_alt_m"] = s.altitude_sigma_m
    return record


def nees_band_3dof() -> tuple[float, float]:
    """The two-sided 95 % band of one 3-dof NEES sample (bus.statistics)."""
    return chi2_band(3)


def health_record(status: Any) -> dict[str, Any]:
    """One /health message of a vehicle's ESTIMATOR_STATUS (bus.mavlink_codec.EstimatorStatus)."""
    return {
        "t_s": status.time_usec * 1e-6,
        "vehicle": status.vehicle_id,
        "gnss_test_ratio": float(status.pos_horiz_ratio),
        "gnss_glitch": bool(status.gps_glitch),
        "horizontal_accuracy_m": float(status.pos_horiz_accuracy_m),
    }


def loop_record(status: Any) -> dict[str, Any]:
    """One /loop message of a vehicle's status report (bus.messages.VehicleStatus)."""
    return {
        "t_s": status.stamp_us * 1e-6,
        "vehicle": status.vehicle_id,
        "cycles": status.cycles,
        "overruns": status.overruns,
        "cycle_p99_us": status.cycle_p99_us,
        "jitter_p99_us": status.jitter_p99_us,
        "v2v_fused": status.v2v_fused,
        "v2v_missing": status.v2v_missing,
    }


def swarm_records(scores: list[Score]) -> list[tuple[int, dict[str, Any]]]:
    """(stamp us, /swarm message) per stamp of ``scores``, in stamp order: the position error and
    NEES of the vehicles scored at that stamp, summed up."""
    by_stamp: dict[int, list[Score]] = {}
    for s in scores:
        by_stamp.setdefault(s.stamp_us, []).append(s)
    return [(stamp, _swarm_record(stamp, group)) for stamp, group in sorted(by_stamp.items())]


def _swarm_record(stamp_us: int, scores: list[Score]) -> dict[str, Any]:
    """The /swarm message of the vehicles scored at ``stamp_us``: RMS and largest error, mean NEES
    (of the finite ones; left out when none is)."""
    errors = [s.position_error_m for s in scores]
    record = {"t_s": stamp_us * 1e-6, "rms_error_m": math.sqrt(sum(e * e for e in errors) / len(errors)),
              "max_error_m": max(errors), "vehicles": len(errors)}  # fmt: skip
    nees = [s.nees for s in scores if math.isfinite(s.nees)]
    if nees:
        record["mean_nees"] = sum(nees) / len(nees)
    return record
