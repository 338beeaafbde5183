"""The ground-station process: owns the fault plan, scores every vehicle's MAVLink estimates against
truth, measures each MAVLink link, logs events, and writes the run directory as it goes.

A restarted ground station appends to the same run directory and picks up the tallies and event
counts already there, so summary.json still covers the whole run.
"""

from __future__ import annotations

import logging
import queue
import time
from collections import Counter
from pathlib import Path

from bus import messages as m
from bus.config import SwarmConfig
from bus.errors import DecodeError
from bus.link_faults import Arrival, LinkFaultStage
from bus.mavlink_codec import EstimatorStatus, MavlinkDecoder, StateEstimate, StatusText, frame_header
from bus.plan import FaultReply, FaultRequest, decode_json, encode_json
from bus.session import Bus, Envelope, LivelinessEvent, Request
from bus.claims import ClaimReply, ClaimRequest
from groundstation.claims import IdRegister
from groundstation.fault_control import FaultControl
from groundstation.link_quality import StreamQuality
from groundstation.mavlink_out import MavlinkForwarder
from groundstation.resume import resume_events, resume_tallies
from groundstation.rundir import RunDirectory
from groundstation.scoring import Scorer
from groundstation.summary import build_summary, build_timing

log = logging.getLogger("swarmloc.groundstation")
REALTIME_LAG_US = 1_000_000
PLAN_REPEAT_S = 1.0


class GroundStation:
    def __init__(self, bus: Bus, config: SwarmConfig, run_dir: Path, *, signing_key: bytes | None = None,
                 forwarder: MavlinkForwarder | None = None) -> None:
        self.bus, self.config = bus, config
        keys, prefix = bus.keys, bus.keys.prefix
        self.inbox: queue.SimpleQueue = queue.SimpleQueue()
        for expr in (f"{prefix}/v/*/truth", f"{prefix}/v/*/mavlink", f"{prefix}/v/*/status", keys.clock(), keys.end()):
            bus.subscribe(expr, self.inbox)
        bus.queryable(keys.fault_request(), self.inbox)
        bus.queryable(keys.claim(), self.inbox)
        self._plan_pub = bus.publisher(keys.fault_plan())
        self.run = RunDirectory(run_dir)
        self.ids = IdRegister(vehicles=config.world.vehicles, path=run_dir / "claims.json")
        self.scorer = Scorer()
        self.decoder = MavlinkDecoder(signing_key=signing_key)
        self.forwarder = forwarder
        self.links = LinkFaultStage("gs", seed=config.world.seed, faults=config.faults)
        self.quality: dict[int, StreamQuality] = {}
        self._stream_stamp_us: dict[int, int] = {}
        self.latency_us: dict[int, list[int]] = {}
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
        self.faults = FaultControl(config.faults, vehicles=config.world.vehicles, log=self._fault_event)
        self.resumed = False
        self._resume(run_dir)
        self._plan_sent_at = 0.0
        self.wall_start: float | None = None
        self.wall_end: float | None = None
        self.on_progress = lambda gs: None
        bus.watch_liveliness(f"{prefix}/alive/vehicle/*", self.inbox)
        bus.declare_token(keys.alive("groundstation", 0))

    def _resume(self, run_dir: Path) -> None:
        """Pick up a run directory a previous ground station of this run was writing."""
        tallies, last_us = resume_tallies(run_dir / "metrics.csv", self.scorer.bounds)
        if not tallies:
            return
        self.scorer.tallies, self.scorer.last_scored_us = tallies, last_us
        self.events = resume_events(run_dir / "events.jsonl")
        self.resumed = True
        self.sim_time_us = max(last_us.values())
        self.faults.resume(self.sim_time_us)
        self.event("groundstation_restarted", scored_until_s=round(self.sim_time_us * 1e-6, 6))

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
            self._on_liveliness(item)
        elif isinstance(item, Request):
            self._on_request(item)
        elif item.key.endswith("/mavlink"):
            self._offer_mavlink(item)
        else:
            self._on_envelope(item)

    def _on_liveliness(self, item: LivelinessEvent) -> None:
        vid = item.key.rsplit("/", 1)[-1]
        if self.resumed and self.previous_tick_us < 0 and item.alive and vid.isdigit():
            self.active.add(int(vid))  # a restarted ground station meets vehicles that joined long ago
            return
        kind = "vehicle_joined" if item.alive else ("vehicle_left" if self._completed(vid) else "vehicle_lost")
        if vid.isdigit():
            (self.active.add if item.alive else self.active.discard)(int(vid))
            (self.departed.discard if item.alive else self.departed.add)(int(vid))
        self.event(kind, vehicle=int(vid) if vid.isdigit() else vid)

    def _on_request(self, request: Request) -> None:
        """`swarm fault ...`: validate, apply, publish the new plan, answer with it. Id claims too."""
        if request.key == self.bus.keys.claim():
            try:
                reply = self.ids.claim(decode_json(ClaimRequest, request.payload))
            except DecodeError as exc:
                reply = ClaimReply(ok=False, error=str(exc))
            request.respond(encode_json(reply))
            if reply.ok:
                self.run.event("vehicle_claimed", self.sim_time_us, vehicle=reply.vehicle_id, restarts=reply.restarts)
            return
        try:
            reply = self.faults.request(decode_json(FaultRequest, request.payload))
        except DecodeError as exc:
            reply = FaultReply(ok=False, error=str(exc), plan=self.faults.plan())
        request.respond(encode_json(reply))
        if reply.ok:
            self.publish_plan()

    def publish_plan(self) -> None:
        plan = self.faults.plan()
        self.links.set_plan(plan.faults)
        self._plan_pub.put(encode_json(plan))
        self._plan_sent_at = time.monotonic()

    def _on_envelope(self, item: Envelope) -> None:
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
        except DecodeError as exc:
            self.events["decode_error"] += 1
            log.warning("ground station dropped a payload on %s: %s", key, exc)

    def _offer_mavlink(self, item: Envelope) -> None:
        """MAVLink frames pass this process's link faults first, stamped with their time_usec; frames
        without one (HEARTBEAT, STATUSTEXT) take the last stamp of their stream, so that what the
        faults do never depends on when a frame happened to arrive (lockstep stays reproducible)."""
        header = frame_header(item.payload)
        vid = self.bus.keys.vehicle_of(item.key)
        if header and header[3] is not None:
            self._stream_stamp_us[vid] = header[3]
        stamp = self._stream_stamp_us.get(vid, 0)
        for frame in self.links.offer(Arrival(item.key, f"v{vid}", "mavlink", stamp, item)):
            self._on_mavlink(frame)

    def _on_mavlink(self, item: Envelope) -> None:
        vid = self.bus.keys.vehicle_of(item.key)
        header = frame_header(item.payload)
        if header is not None:
            self.quality.setdefault(vid, StreamQuality()).see(header[1])  # as a GCS counts its link
        try:
            decoded = self.decoder.decode(item.payload)
        except DecodeError as exc:
            self.rejected[vid] += 1
            self.events["decode_error"] += 1
            log.warning("ground station rejected a MAVLink frame on %s: %s", item.key, exc)
            return
        if self.forwarder is not None:
            self.forwarder.forward(item.payload)
        if isinstance(decoded, StateEstimate):
            lat = self.latency_us.setdefault(vid, [0, 0, 0])  # count, sum, max (us)
            delay = self.sim_time_us - decoded.time_usec
            lat[0], lat[1], lat[2] = lat[0] + 1, lat[1] + delay, max(lat[2], delay)
            self.scorer.add_estimate(decoded)
            self.latest_estimate_us[decoded.vehicle_id] = max(decoded.time_usec, self.latest_estimate_us.get(vid, -1))
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
        self.faults.advance(tick.stamp_us)
        for frame in self.links.release(tick.stamp_us, self._stream_passed):
            self._on_mavlink(frame)
        if self.config.clock.mode == "lockstep" and self.previous_tick_us >= 0:
            self.run.write_scores(self.scorer.release(self._lockstep_watermark()))
        elif self.config.clock.mode == "realtime":
            self.run.write_scores(self.scorer.release(tick.stamp_us - REALTIME_LAG_US))
        self.previous_tick_us = tick.stamp_us
        if time.monotonic() - self._plan_sent_at > PLAN_REPEAT_S:
            self.publish_plan()  # repeated, so that restarted processes learn it
        self.on_progress(self)

    def _stream_passed(self, arrival: Arrival, due_us: int) -> bool:
        """A held frame comes out once its stream has delivered a frame stamped at or after its due
        time (zenoh keeps order within a key, so nothing earlier is still on its way), or once its
        vehicle has left. Release order then never depends on when frames arrived."""
        vid = self.bus.keys.vehicle_of(arrival.key)
        return self._stream_stamp_us.get(vid, -1) >= due_us or vid not in self.active

    def _completed(self, vid: str) -> bool:
        """A vehicle whose estimates reached the end of the run left normally; otherwise it was lost."""
        end_us = round(self.config.clock.duration_s * 1e6)
        return vid.isdigit() and self.latest_estimate_us.get(int(vid), -1) >= end_us

    def _lockstep_watermark(self) -> int:
        """Estimates up to here can be scored in (time, vehicle) order: every live vehicle has
        published past it, truth covers it, and no delay fault still holds an older estimate.
        Zenoh keeps order within a key, not across keys, so each stream's own progress counts."""
        marks = [self.previous_tick_us, *self.latest_truth_us.values()]
        marks += [self.latest_estimate_us.get(vid, -1) for vid in self.active]
        held = self.links.held_min_stamp()
        return min(marks) if held is None else min(*marks, held - 1)

    def finish(self, status: str) -> dict:
        """Score everything left, write summary.json and timing.json, close the files."""
        for frame in self.links.release(2**62):
            self._on_mavlink(frame)
        self.run.write_scores(self.scorer.release(float("inf")))
        lost = sorted(vid for vid in self.departed if not self._completed(str(vid)))
        if lost:
            self.events["vehicle_lost"] = len(lost)
        self.event("run_ended", status=status, vehicles_lost=lost)
        summary = build_summary(self.config, self.scorer, self.statuses, dict(self.rejected),
                                dict(sorted(self.events.items())), status, self.faults.faults, self.quality)
        summary["mavlink_rejected_by_reason"] = dict(sorted(self.decoder.rejected.items()))
        self.run.write_json("summary.json", summary)
        wall_s = (self.wall_end or time.perf_counter()) - (self.wall_start or time.perf_counter())
        self.run.write_json("timing.json", build_timing(self.statuses, self.sim_time_us * 1e-6, wall_s, self.latency_us))
        self.run.close()
        return summary
