"""summary.json (deterministic in lockstep) and timing.json (wall-clock loop statistics)."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from typing import Any

from bus import messages as m
from bus.config import SwarmConfig
from bus.consistency import nis_summary
from bus.messages import VehicleStatus
from bus.rejections import REASONS, Rejections, counts_to_dict
from bus.statistics import POSE_NEES_DOF
from groundstation.link_quality import StreamQuality
from groundstation.scoring import AltitudeTally, Scorer, Tally


def _round(value: float) -> float:
    return round(value, 6)


def build_summary(
    config: SwarmConfig,
    scorer: Scorer,
    statuses: dict[int, VehicleStatus],
    events: dict[str, int],
    status: str,
    faults: Sequence = (),
    intake: Any = None,
    rejected: Mapping[str, tuple[int, ...]] | None = None,
) -> dict[str, Any]:
    """Per-vehicle and swarm RMSE and NEES, counters, MAVLink link quality, the faults of the plan,
    rejected input by process and reason, and how the run ended."""
    quality = intake.quality if intake is not None else {}
    per_vehicle_rejected = intake.rejected_by_vehicle if intake is not None else {}
    ids = sorted(set(scorer.tallies) | set(statuses))
    vehicles = {
        str(vid): vehicle_entry(
            scorer.tallies.get(vid), statuses.get(vid), per_vehicle_rejected.get(vid, 0), quality.get(vid)
        )
        for vid in ids
    }
    return {
        "name": config.name,
        "status": status,
        "mode": config.clock.mode,
        "seed": config.world.seed,
        "duration_s": config.clock.duration_s,
        "vehicles": vehicles,
        "swarm": swarm_entry(scorer, [scorer.tallies[vid] for vid in ids if vid in scorer.tallies]),
        "events": events,
        "faults": {
            "total": len(faults),
            "by_kind": dict(sorted(Counter(f.kind for f in faults).items())),
            "names": [f.name for f in faults],
        },
        "rejected": rejected_entry(rejected or {}),
    }


def vehicle_entry(
    tally: Tally | None, st: VehicleStatus | None, mavlink_rejected: int, link: StreamQuality | None
) -> dict[str, Any]:
    """One vehicle's scores (``tally``: its scorer tally, None before any estimate), the counters of
    its last status (None before one came), its MAVLink frames rejected and its link's quality."""
    entry: dict[str, Any] = {"samples": tally.samples if tally else 0}
    if tally and tally.samples:
        entry.update(
            rmse_m=_round(math.sqrt(tally.sum_sq_position_m2 / tally.samples)),
            max_error_m=_round(tally.max_position_error_m),
            anees=_round(tally.sum_nees / tally.samples),
            nees_inside_95=_round(tally.nees_inside / tally.samples),
            consistency=tally.consistency.result().as_dict(),
        )
    if tally and tally.altitude is not None:
        entry["altitude"] = altitude_entry(tally.altitude)
    if st is not None:
        entry.update(
            cycles=st.cycles,
            overruns=st.overruns,
            gnss_rejected=st.rejected_gnss,
            dropped_stale=st.dropped_stale,
            decode_errors=st.decode_errors,
            reset_counter=st.reset_counter,
            sensor_duplicates=st.duplicates,
            sensor_samples_lost=st.samples_lost,
            late_fused=st.late_fused,
            v2v_fused=st.v2v_fused,
            v2v_missing=st.v2v_missing,
        )
        if st.frames_used:  # a camera vehicle running SLAM
            entry.update(landmarks=st.landmarks, camera_frames_used=st.frames_used)
        nis = nis_summary(st.nis)
        if nis:
            entry["nis"] = nis
    entry["mavlink_rejected"] = mavlink_rejected
    if link is not None:
        entry["mavlink_link"] = link.as_dict()
    return entry


def altitude_entry(tally: AltitudeTally) -> dict[str, Any]:
    """A vehicle's height above its launch point, scored (groundstation.scoring): RMSE and largest
    error (m), ANEES and its consistency (1 dof)."""
    return {
        "samples": tally.samples,
        "rmse_m": _round(math.sqrt(tally.sum_sq_m2 / tally.samples)),
        "max_error_m": _round(tally.max_error_m),
        "anees": _round(tally.sum_nees / tally.samples),
        "nees_dof": 1,
        "consistency": tally.consistency.result().as_dict(),
    }


def swarm_entry(scorer: Scorer, tallies: list[Tally]) -> dict[str, Any]:
    """The swarm's RMSE and ANEES over every scored estimate of ``tallies`` (summed in vehicle order),
    and what the scorer could not score."""
    total_n = sum(t.samples for t in tallies)
    total_sq = sum(t.sum_sq_position_m2 for t in tallies)
    total_nees = sum(t.sum_nees for t in tallies)
    return {
        "samples": total_n,
        "rmse_m": _round(math.sqrt(total_sq / total_n)) if total_n else None,
        "anees": _round(total_nees / total_n) if total_n else None,
        "nees_dof": POSE_NEES_DOF,
        "nees_bounds_95": [_round(b) for b in scorer.bounds],
        "unscored": scorer.unscored,
        "in_truth_gaps": scorer.in_truth_gaps,
        "duplicate_estimates": scorer.duplicates,
        "late_estimates": scorer.late,
    }


def rejected_entry(rejected: Mapping[str, tuple[int, ...]]) -> dict[str, Any]:
    """Input rejected, by process (only those that rejected any) and by reason over every process."""
    by_process = {name: counts_to_dict(counts) for name, counts in sorted(rejected.items())}
    totals: Counter = Counter()
    for counts in by_process.values():
        totals.update(counts)
    return {
        "by_process": {k: v for k, v in by_process.items() if v},
        "by_reason": {r: totals[r] for r in REASONS if totals[r]},
    }


def build_timing(
    statuses: dict[int, VehicleStatus], sim_s: float, wall_s: float, latency_us: Mapping[int, list[int]] | None = None
) -> dict[str, Any]:
    """Wall-clock loop statistics per vehicle (with the SCHED_FIFO priority its realtime loop was
    granted, 0 under the fair scheduler), the MAVLink latency in sim time (arrival tick minus
    time_usec, so quantised to the clock tick) and the run's real-time factor (sim s per wall s):
    never reproducible, so kept out of summary.json."""
    latency_us = latency_us or {}
    vehicles = {
        str(vid): {
            "cycles": st.cycles,
            "overruns": st.overruns,
            "overrun_rate": _round(st.overruns / st.cycles) if st.cycles else 0.0,
            "jitter_p99_us": _round(st.jitter_p99_us),
            "cycle_p99_us": _round(st.cycle_p99_us),
            "loop_priority": st.loop_priority,
            "v2v_received": st.v2v_received,
        }
        for vid, st in sorted(statuses.items())
    }
    for vid, (count, total, worst) in latency_us.items():
        if count:
            vehicles.setdefault(str(vid), {}).update(
                mavlink_latency_mean_s=_round(total / count * 1e-6), mavlink_latency_max_s=_round(worst * 1e-6)
            )
    return {
        "sim_s": _round(sim_s),
        "wall_s": _round(wall_s),
        "real_time_factor": _round(sim_s / wall_s) if wall_s > 0 else None,
        "vehicles": vehicles,
    }


def rejected_by_process(
    own: Rejections, ended: m.RunEnd | None, statuses: dict[int, Any]
) -> dict[str, tuple[int, ...]]:
    """Rejected input by process: the ground station's own, the world's (from its run end) and every
    vehicle's (from its last status)."""
    out = {"groundstation": own.as_counts()}
    if ended is not None and ended.rejected:
        out["world"] = ended.rejected
    out.update({f"vehicle-{vid}": st.rejected for vid, st in sorted(statuses.items()) if st.rejected})
    return out
