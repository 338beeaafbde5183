"""summary.json (deterministic in lockstep) and timing.json (wall-clock loop statistics)."""

from __future__ import annotations

import math
from typing import Any

from bus.config import SwarmConfig
from bus.messages import VehicleStatus
from groundstation.scoring import NEES_DOF, Scorer


def _round(value: float) -> float:
    return round(value, 6)


def build_summary(config: SwarmConfig, scorer: Scorer, statuses: dict[int, VehicleStatus],
                  rejected: dict[int, int], events: dict[str, int], status: str) -> dict[str, Any]:
    """Per-vehicle and swarm RMSE and NEES, counters, and how the run ended."""
    vehicles: dict[str, Any] = {}
    total_sq, total_n, total_nees = 0.0, 0, 0.0
    for vid in sorted(set(scorer.tallies) | set(statuses)):
        tally = scorer.tallies.get(vid)
        st = statuses.get(vid)
        entry: dict[str, Any] = {"samples": tally.samples if tally else 0}
        if tally and tally.samples:
            entry.update(rmse_m=_round(math.sqrt(tally.sum_sq_position_m2 / tally.samples)),
                         max_error_m=_round(tally.max_position_error_m),
                         anees=_round(tally.sum_nees / tally.samples),
                         nees_inside_95=_round(tally.nees_inside / tally.samples))
            total_sq, total_n, total_nees = total_sq + tally.sum_sq_position_m2, total_n + tally.samples, total_nees + tally.sum_nees
        if st is not None:
            entry.update(cycles=st.cycles, overruns=st.overruns, gnss_rejected=st.rejected_gnss,
                         dropped_stale=st.dropped_stale, decode_errors=st.decode_errors)
        entry["mavlink_rejected"] = rejected.get(vid, 0)
        vehicles[str(vid)] = entry
    swarm = {"samples": total_n, "rmse_m": _round(math.sqrt(total_sq / total_n)) if total_n else None,
             "anees": _round(total_nees / total_n) if total_n else None, "nees_dof": NEES_DOF,
             "nees_bounds_95": [_round(b) for b in scorer.bounds], "unscored": scorer.unscored}
    return {"name": config.name, "status": status, "mode": config.clock.mode, "seed": config.world.seed,
            "duration_s": config.clock.duration_s, "vehicles": vehicles, "swarm": swarm, "events": events}


def build_timing(statuses: dict[int, VehicleStatus], sim_s: float, wall_s: float) -> dict[str, Any]:
    """Wall-clock loop statistics per vehicle and the run's real-time factor (sim s per wall s):
    never reproducible, so kept out of summary.json."""
    vehicles = {str(vid): {"cycles": st.cycles, "overruns": st.overruns,
                       "overrun_rate": _round(st.overruns / st.cycles) if st.cycles else 0.0,
                       "jitter_p99_us": _round(st.jitter_p99_us), "cycle_p99_us": _round(st.cycle_p99_us)}
                for vid, st in sorted(statuses.items())}
    return {"sim_s": _round(sim_s), "wall_s": _round(wall_s),
            "real_time_factor": _round(sim_s / wall_s) if wall_s > 0 else None, "vehicles": vehicles}
