"""The ground-station process: scores every vehicle's MAVLink estimates against truth, logs events,
and writes the run directory as it goes.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import Counter
from pathlib import Path

from bus import messages as m
from bus.config import SwarmConfig
from bus.errors import DecodeError
from bus.mavlink_codec import EstimatorStatus, MavlinkDecoder, StateEstimate, StatusText
from bus.session import Bus, Envelope, LivelinessEvent
from groundstation.fault_log import FaultLog
from groundstation.rundir import RunDirectory
from groundstation.scoring import Scorer
from groundstation.summary import build_summary, build_timing

log = logging.getLogger("swarmloc.groundstation")
REALTIME_LAG_US = 1_000_000
END_GRACE_S = 0.3


class GroundStation:
    def __init__(self, bus: Bus, config: SwarmConfig, run_dir: Path) -> None:
        self.bus, self.config = bus, config
        keys, prefix = bus.keys, bus.keys.prefix
        self.inbox: queue.SimpleQueue = queue.SimpleQueue()
        for expr in (f"{prefix}/v/*/truth", f"{prefix}/v/*/mavlink", f"{prefix}/v/*/status", keys.clock(), keys.end()):
            bus.subscribe(expr, self.inbox)
        bus.watch_liveliness(f"{prefix}/alive/vehicle/*", self.inbox)
        bus.declare_token(keys.alive("groundstation", 0))
        self.run = RunDirectory(run_dir)
        self.scorer = Scorer()
        self.decoder = MavlinkDecoder()
        self.statuses: dict[int, m.VehicleStatus] = {}
        self.rejected: Counter[int] = Counter()
        self.events: Counter[str] = Counter()
        self.sim_time_us = 0
        self.previous_tick_us = -1
        self.ended = False
        self.final_seen = False
        self.active: set[int] = set()  # vehicles alive on the bus
        self.departed: set[int] = set()
        self.latest_estimate_us: dict[int, int] = {}
        self.latest_truth_us: dict[int, int] = {}
        self.gnss_glitch: dict[int, bool] = {}
        self.fault_log = FaultLog(config.faults, self._fault_event)
        self.wall_start: float | None = None
        self.wall_end: float | None = None
        self.on_progress = lambda gs: None

    def event(self, kind: str, **fields: object) -> None:
        """Log an event; departures after the final tick are logged but not counted in the summary
        (they race with the end of the run, and summary.json must be reproducible)."""
        if kind not in ("vehicle_left", "vehicle_lost"):  # departures are counted in finish()
            self.events[kind] += 1
        self.run.event(kind, self.sim_time_us, **fields)

    def _fault_event(self, kind: str, stamp_us: int, **fields: object) -> None:
        self.events[kind] += 1
        self.run.event(kind, stamp_us, **fields)

    def handle(self, item: object) -> None:
        if isinstance(item, LivelinessEvent):
            vid = item.key.rsplit("/", 1)[-1]
            kind = "vehicle_joined" if item.alive else ("vehicle_left" if self._completed(vid) else "vehicle_lost")
            if vid.isdigit():
                (self.active.add if item.alive else self.active.discard)(int(vid))
                (self.departed.discard if item.alive else self.departed.add)(int(vid))
            self.event(kind, vehicle=int(vid) if vid.isdigit() else vid)
            return
        keys, key = self.bus.keys, item.key
        try:
            if key == keys.clock():
                self._on_tick(m.decode(m.ClockTick, item.payload))
            elif key == keys.end():
                self.ended, self.wall_end = True, time.perf_counter()
            elif key.endswith("/truth"):
                truth = m.decode(m.Truth, item.payload)
                self.scorer.add_truth(truth)
                self.latest_truth_us[truth.vehicle_id] = truth.stamp_us
            elif key.endswith("/status"):
                status = m.decode(m.VehicleStatus, item.payload)
                self.statuses[status.vehicle_id] = status
            elif key.endswith("/mavlink"):
                self._on_mavlink(item)
        except DecodeError as exc:
            self.events["decode_error"] += 1
            log.warning("ground station dropped a payload on %s: %s", key, exc)

    def _on_mavlink(self, item: Envelope) -> None:
        try:
            decoded = self.decoder.decode(item.payload)
        except DecodeError:
            self.rejected[self.bus.keys.vehicle_of(item.key)] += 1
            raise
        if isinstance(decoded, StateEstimate):
            self.scorer.add_estimate(decoded)
            self.latest_estimate_us[decoded.vehicle_id] = decoded.time_usec
        elif isinstance(decoded, EstimatorStatus):
            self._on_estimator_status(decoded)
        elif isinstance(decoded, StatusText):
            self.run.event("vehicle_message", self.sim_time_us, vehicle=decoded.vehicle_id,
                           severity=decoded.severity, text=decoded.text)
            if decoded.text.startswith("estimator reset"):
                self.event("estimator_reset", vehicle=decoded.vehicle_id, text=decoded.text)

    def _on_estimator_status(self, status: EstimatorStatus) -> None:
        """GNSS health changes (the GPS glitch flag) become events, stamped with the vehicle's time."""
        was = self.gnss_glitch.get(status.vehicle_id, False)
        self.gnss_glitch[status.vehicle_id] = status.gps_glitch
        if status.gps_glitch != was:
            kind = "gnss_unhealthy" if status.gps_glitch else "gnss_healthy"
            self.events[kind] += 1
            self.run.event(kind, status.time_usec, vehicle=status.vehicle_id,
                           test_ratio=round(status.pos_horiz_ratio, 3))

    def _on_tick(self, tick: m.ClockTick) -> None:
        """Lockstep: tick k means every estimate up to tick k-1 has been published and received."""
        if tick.tick == 0:
            self.wall_start = time.perf_counter()
            self.event("run_started", mode=self.config.clock.mode)
        self.final_seen = self.final_seen or tick.final
        self.sim_time_us = tick.stamp_us
        self.fault_log.advance(tick.stamp_us)
        if self.config.clock.mode == "lockstep" and self.previous_tick_us >= 0:
            self.run.write_scores(self.scorer.release(self._lockstep_watermark()))
        elif self.config.clock.mode == "realtime":
            self.run.write_scores(self.scorer.release(tick.stamp_us - REALTIME_LAG_US))
        self.previous_tick_us = tick.stamp_us
        self.on_progress(self)

    def _completed(self, vid: str) -> bool:
        """A vehicle whose estimates reached the end of the run left normally; otherwise it was lost."""
        end_us = round(self.config.clock.duration_s * 1e6)
        return vid.isdigit() and self.latest_estimate_us.get(int(vid), -1) >= end_us

    def _lockstep_watermark(self) -> int:
        """Estimates up to here can be scored in (time, vehicle) order: every live vehicle has
        published past it and truth covers it. Zenoh keeps order within a key, not across keys,
        so each stream's own progress is what counts, not the clock tick alone."""
        marks = [self.previous_tick_us, *self.latest_truth_us.values()]
        marks += [self.latest_estimate_us.get(vid, -1) for vid in self.active]
        return min(marks)

    def finish(self, status: str) -> dict:
        """Score everything left, write summary.json and timing.json, close the files."""
        self.run.write_scores(self.scorer.release(float("inf")))
        lost = sorted(vid for vid in self.departed if not self._completed(str(vid)))
        if lost:
            self.events["vehicle_lost"] = len(lost)
        self.event("run_ended", status=status, vehicles_lost=lost)
        summary = build_summary(self.config, self.scorer, self.statuses, dict(self.rejected),
                                dict(sorted(self.events.items())), status)
        self.run.write_json("summary.json", summary)
        wall_s = (self.wall_end or time.perf_counter()) - (self.wall_start or time.perf_counter())
        self.run.write_json("timing.json", build_timing(self.statuses, self.sim_time_us * 1e-6, wall_s))
        self.run.close()
        return summary


def run_groundstation(bus: Bus, config: SwarmConfig, run_dir: Path, stop: threading.Event,
                      on_progress=None) -> dict:
    """Score until the world ends the run (or ``stop`` is set); returns the summary."""
    gs = GroundStation(bus, config, run_dir)
    if on_progress is not None:
        gs.on_progress = on_progress
    while not gs.ended and not stop.is_set():
        try:
            gs.handle(gs.inbox.get(timeout=0.2))
        except queue.Empty:
            gs.run.maybe_flush()
    _drain(gs, END_GRACE_S)  # keys are not ordered among each other: let stragglers land
    return gs.finish("complete" if gs.ended else "interrupted")


def _drain(gs: GroundStation, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            gs.handle(gs.inbox.get(timeout=max(0.0, deadline - time.monotonic())))
        except queue.Empty:
            return
