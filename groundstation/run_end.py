"""The end of a run at the ground station (groundstation.node): everything still held is scored, the
vehicles that left without completing are counted lost, and summary.json, the SLAM maps and
timing.json are written before the files close."""

from __future__ import annotations

import time
from collections import Counter
from typing import Protocol

from bus import messages as m
from bus.config import SwarmConfig
from bus.landmark_map import map_record
from bus.mailbox import Mailbox
from bus.rejections import Rejections
from groundstation.fault_control import FaultControl
from groundstation.mavlink_in import MavlinkIntake
from groundstation.membership import Presence
from groundstation.rundir import RunDirectory
from groundstation.scoring import Scorer
from groundstation.summary import build_summary, build_timing, rejected_by_process
from groundstation.vehicle_reports import VehicleReports
from groundstation.vehicle_streams import VehicleStreams


class Finishing(Protocol):
    """What a run's end is read off (a groundstation.node.GroundStation)."""

    config: SwarmConfig
    intake: MavlinkIntake
    streams: VehicleStreams
    run: RunDirectory
    scorer: Scorer
    presence: Presence
    events: Counter[str]
    rejections: Rejections
    mailbox: Mailbox
    reports: VehicleReports
    faults: FaultControl
    ended: m.RunEnd | None
    final_departures: list[int]
    sim_time_us: int
    wall_start: float | None
    wall_end: float | None

    def event(self, kind: str, **fields: object) -> None: ...
    def completed(self, vid: int) -> bool: ...


def finish_run(gs: Finishing, status: str) -> dict:
    """Score everything left, write summary.json, the maps and timing.json, close the files; the
    summary."""
    for vid, frame in gs.intake.release(2**62):
        gs.streams.frame(vid, frame, gs.sim_time_us)
    gs.run.write_scores(gs.scorer.release(float("inf")))
    for vid in gs.final_departures:
        gs.event("vehicle_left" if gs.completed(vid) else "vehicle_lost", vehicle=vid)
    lost = sorted(vid for vid in gs.presence.departed if not gs.completed(vid))
    if lost:
        gs.events["vehicle_lost"] = len(lost)
    gs.event("run_ended", status=status, vehicles_lost=lost)
    gs.rejections.counts["inbox_full"] = gs.mailbox.dropped()
    statuses = gs.reports.statuses
    summary = build_summary(
        gs.config,
        gs.scorer,
        statuses,
        dict(sorted(gs.events.items())),
        status,
        gs.faults.faults,
        gs.intake,
        rejected_by_process(gs.rejections, gs.ended, statuses),
    )
    gs.run.write_json("summary.json", summary)
    gs.run.write_maps({vid: map_record(lmap) for vid, lmap in gs.reports.maps.items()})
    wall_s = (gs.wall_end or time.perf_counter()) - (gs.wall_start or time.perf_counter())
    timing = build_timing(statuses, gs.sim_time_us * 1e-6, wall_s, gs.streams.latency_us)
    gs.run.write_json("timing.json", timing)
    gs.run.close()
    return summary
