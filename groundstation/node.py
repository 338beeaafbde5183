"""The ground-station process: owns the fault plan, scores every vehicle's MAVLink estimates against
truth, measures each MAVLink link, logs events, and writes the run directory as it goes.

Everything that arrives is parsed totally and, when bad, counted by reason (summary.json) and logged
once per kind. A restarted ground station appends to the same run directory and picks up the tallies
and event counts already there, so summary.json still covers the whole run.
"""

from __future__ import annotations

import logging
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bus import feed
from bus import messages as m
from bus.clock_config import ClockMode
from bus.config import SwarmConfig
from bus.errors import DecodeError
from bus.estimators import ESTIMATORS
from bus.link_faults import Arrival
from bus.mailbox import Oversized
from bus.plan import encode_json
from bus.rejections import Rejections
from bus.session import Bus, Envelope, LivelinessEvent, Request
from groundstation.claims import IdRegister
from groundstation.fault_control import FaultControl
from groundstation.layout import swarm_layouts
from groundstation.mavlink_in import MavlinkIntake
from groundstation.mavlink_out import MavlinkForwarder
from groundstation.membership import Presence
from groundstation.recording_start import open_recording
from groundstation.requests import Requests
from groundstation.resume import resume_events, resume_run
from groundstation.run_end import finish_run
from groundstation.rundir import RunDirectory
from groundstation.scoring import Scorer
from groundstation.station_bus import station_mailbox
from groundstation.tick_ack import TickAck, paced_ahead, watermark_us
from groundstation.vehicle_reports import VehicleReports
from groundstation.vehicle_streams import VehicleStreams

log = logging.getLogger("swarmloc.groundstation")
REALTIME_LAG_US = 1_000_000
PLAN_REPEAT_S = 1.0


class GroundStation:
    def __init__(
        self,
        bus: Bus,
        config: SwarmConfig,
        run_dir: Path,
        *,
        master_key: bytes | None = None,
        forwarder: MavlinkForwarder | None = None,
    ) -> None:
        self.bus, self.config = bus, config
        keys = bus.keys
        self.rejections = Rejections(log, "ground station")
        self.mailbox, control = station_mailbox(bus)
        self._plan_pub, self._ack_pub = bus.publisher(keys.fault_plan()), bus.publisher(keys.ack("gs"))
        self.run = RunDirectory(run_dir)  # creates the directory the recording goes in
        self.run.recording = open_recording(run_dir, config.view, config.world.vehicles)
        if self.run.recording is not None:
            heights = ESTIMATORS[config.vehicle.estimator].estimates_height
            self.run.write_layouts(swarm_layouts(config.world, heights))
        if self.run.recording is not None:
            self.rejections.on_first = self._show_rejection
        self.ids = IdRegister(vehicles=config.world.vehicles, path=run_dir / "claims.json", master_key=master_key)
        self.scorer = Scorer()
        self.intake = MavlinkIntake(
            vehicles=config.world.vehicles,
            master_key=master_key,
            fault_seed=config.fault_seed,
            faults=config.faults,
            rejections=self.rejections,
        )
        self.streams = VehicleStreams(self.intake, self.scorer, self.run, self._event_at, self.rejections, forwarder)
        self.reports = VehicleReports(config.world.vehicles, self.rejections)  # loop statistics, SLAM maps
        self.events: Counter[str] = Counter()
        self.sim_time_us = 0
        self.previous_tick_us = -1
        self.published_us = -1  # lockstep: every estimate up to here is published (the tick before the last)
        self.ended: m.RunEnd | None = None
        self.final_seen = False
        # vehicles that left after the final tick went out: whether they completed is known only at the
        # end (their last estimate and the world's end race their departure), so their event waits
        self.final_departures: list[int] = []
        self.tick_members: set[int] | None = None  # lockstep: the vehicles the world's last tick waited for
        self.latest_truth_us = -1
        self.truth_tick = -1  # the newest tick whose truth batch arrived
        self.faults = FaultControl(config.faults, vehicles=config.world.vehicles, log=self._event_at)
        self.requests = Requests(keys, self.faults, self.ids, self.rejections, self.run)
        self.resumed = False
        self._resume(run_dir)
        self.presence = Presence(resumed=self.resumed)
        self._plan_sent_at = 0.0
        self._ack = TickAck()
        self.wall_start: float | None = None
        self.wall_end: float | None = None
        self.on_progress = lambda gs: None
        self._handlers: dict[type, Callable[[Any], None]] = {
            LivelinessEvent: self._on_liveliness,
            Request: self._on_request,
            Oversized: lambda item: self.rejections.reject("oversized", item.key, f"{item.size} bytes"),
            Envelope: self._on_envelope,
        }
        bus.watch_liveliness(keys.alive("vehicle", "*"), control)
        bus.watch_liveliness(keys.alive("world", "*"), control)
        bus.declare_token(keys.alive("groundstation", 0))

    def _resume(self, run_dir: Path) -> None:
        """Pick up a run directory a previous ground station of this run was writing."""
        found = resume_run(run_dir, self.scorer.bounds)
        if found is None:
            return
        self.scorer.tallies, self.scorer.last_scored_us = found
        self.events, self.resumed = resume_events(run_dir / "events.jsonl"), True
        self.sim_time_us = max(self.scorer.last_scored_us.values())
        self.faults.resume(self.sim_time_us)
        self.event("groundstation_restarted", scored_until_s=round(self.sim_time_us * 1e-6, 6))

    def event(self, kind: str, **fields: object) -> None:
        """Log an event; departures after the final tick are logged but not counted in the summary
        (they race with the end of the run, and summary.json must be reproducible)."""
        if kind not in ("vehicle_left", "vehicle_lost"):  # departures are counted in finish()
            self.events[kind] += 1
        self.run.event(kind, self.sim_time_us, **fields)

    def _event_at(self, kind: str, stamp_us: int, **fields: object) -> None:
        self.events[kind] += 1
        self.run.event(kind, stamp_us, **fields)

    def handle(self, item: object) -> None:
        """One mailbox item, by its type: a liveliness token, a request, an oversized payload (counted),
        a message on a key."""
        handler = self._handlers.get(type(item))
        if handler is not None:
            handler(item)

    def _on_liveliness(self, item: LivelinessEvent) -> None:
        parsed = self.bus.keys.parse(item.key)
        if parsed is None or parsed.kind != "alive":
            self.rejections.reject("bad_key", "liveliness", repr(item.key))
            return
        vid = parsed.vehicle_id
        if parsed.role == "vehicle" and (vid is None or vid > self.config.world.vehicles):
            self.rejections.reject("unknown_vehicle", item.key, "not a vehicle of this swarm")
            return
        before_first_tick = self.resumed and self.previous_tick_us < 0
        kind = self.presence.token(parsed.role, vid, item.alive, before_first_tick, self.completed)
        if kind is not None and self.final_seen and not item.alive:
            self.final_departures.append(vid)  # left or lost: said at the end (groundstation.run_end)
        elif kind is not None and self.config.clock.mode is not ClockMode.LOCKSTEP:
            self.event(kind, vehicle=vid)  # lockstep: the world's ticks say who joined and left when

    def _log_membership(self, tick: m.ClockTick) -> None:
        """Lockstep: joins and departures as the world's ticks say, stamped at the start of the tick's
        interval (the previous tick's stamp)."""
        since_us = self.previous_tick_us if self.previous_tick_us >= 0 else tick.stamp_us
        for kind, vid in self.presence.tick(tick.members, self.previous_tick_us, self.completed):
            if kind == "vehicle_joined":  # departures are counted at the end
                self.events[kind] += 1
            self.run.event(kind, since_us, vehicle=vid)

    def _on_request(self, request: Request) -> None:
        """`swarm fault ...` or an id claim (groundstation.requests); a changed plan goes out at once."""
        if self.requests.answer(request, now_us=self.sim_time_us, alive=self.presence.active):
            self.publish_plan()

    def publish_plan(self) -> None:
        plan = self.faults.plan()
        self.intake.links.set_plan(plan.faults)
        self._plan_pub.put(encode_json(plan))
        self._plan_sent_at = time.monotonic()

    def _on_envelope(self, item: Envelope) -> None:
        keys, key = self.bus.keys, item.key
        parsed = keys.parse(key)
        try:
            if key == keys.clock():
                self._on_tick(m.decode(m.ClockTick, item.payload))
            elif key == keys.end():
                if self.ended is None:  # the world says it again until we acknowledge it
                    self.ended, self.wall_end = m.decode(m.RunEnd, item.payload), time.perf_counter()
                self._ack_pub.put(m.encode(m.GroundStationAck(self.ended.tick + 1)))  # "got the end"
            elif key == keys.truth():
                self._on_truth(feed.decode_truth(item.payload))
            elif parsed is None or parsed.kind != "vehicle":
                self.rejections.reject("bad_key", "subscription", repr(key))
            elif parsed.topic == "mavlink":
                for vid, frame in self.intake.offer(key, parsed.vehicle_id, item.payload):
                    self.streams.frame(vid, frame, self.sim_time_us)
            elif parsed.topic == "status":
                self.reports.offer_and_show(parsed.vehicle_id, item.payload, self.run.recording)
        except DecodeError as exc:
            self.rejections.reject("malformed", key, str(exc))

    def _show_rejection(self, reason: str, where: str, detail: str) -> None:
        """The first rejected input of a kind, in the live view and run.mcap (it is counted in summary.json)."""
        self.run.recording.message(self.sim_time_us, f"rejected input ({reason}) on {where}: {detail or '-'}")

    def _on_truth(self, batch: feed.TruthBatch) -> None:
        self.truth_tick = max(self.truth_tick, batch.tick)
        self.latest_truth_us = max(self.latest_truth_us, self.scorer.add_truth_batch(batch))
        if len(batch.stamps_us) and self.run.recording is not None:
            last = batch.rows[-1, :, :2]
            where = {vid: last[n] for n, vid in enumerate(batch.vehicle_ids.tolist()) if np.isfinite(last[n]).all()}
            self.run.recording.ranging(int(batch.stamps_us[-1]), batch.pairs, where)

    def _on_tick(self, tick: m.ClockTick) -> None:
        """Lockstep: tick k means every estimate up to tick k-1 has been published."""
        if tick.tick == 0 and self.wall_start is None:
            self.wall_start = time.perf_counter()
            self.event("run_started", mode=self.config.clock.mode)
        self.final_seen = self.final_seen or tick.final
        self.sim_time_us = max(self.sim_time_us, tick.stamp_us)
        self.tick_members = set(tick.members) or None  # none listed: liveliness decides
        if self.config.clock.mode is ClockMode.LOCKSTEP:
            self._log_membership(tick)
        self.faults.advance(tick.stamp_us)
        if self.run.recording is not None:
            self.run.recording.zones(tick.stamp_us, self.faults.faults)
            overflows = self.run.recording.overflows()
            if overflows:
                self.event("live_view_overflow", times=overflows)
        for vid, frame in self.intake.release(tick.stamp_us, self._stream_passed):
            self.streams.frame(vid, frame, self.sim_time_us)
        if self.config.clock.mode is ClockMode.LOCKSTEP and self.previous_tick_us >= 0:
            self.published_us = self.previous_tick_us  # tick k: every estimate up to tick k-1 is published
            self._score_published()
        elif self.config.clock.mode is ClockMode.REALTIME:
            self.run.write_scores(self.scorer.release(tick.stamp_us - REALTIME_LAG_US))
        self.previous_tick_us = tick.stamp_us
        if time.monotonic() - self._plan_sent_at > PLAN_REPEAT_S:
            self.publish_plan()  # repeated, so that restarted processes learn it
        self._ack.came(tick.tick, tick.running)
        self.on_progress(self)

    def ack_if_drained(self) -> None:
        """Acknowledge the newest clock tick once nothing is waiting in the mailbox and, in lockstep,
        a paced live view is not ahead and the tick before is in (groundstation.tick_ack): the clock's
        lane is served first, so acknowledging on receipt would let a backlog of estimates grow
        without bound behind it (lockstep backpressure, and what a killed ground station loses)."""
        if self._ack.due is None or not self.mailbox.empty():
            return
        if self.config.clock.mode is ClockMode.LOCKSTEP:
            view, period_us = self.config.view, round(1e6 / self.config.vehicle.mavlink_rate_hz)
            if paced_ahead(view.live_speed if view.live else None, self.wall_start, self.sim_time_us):
                return
            stamps = self.intake.stream_stamp_us
            if not self._ack.previous_tick_in(self.published_us, period_us, stamps, self.latest_truth_us):
                return
        if self.published_us >= 0:  # the streams filed since the tick came may let more be scored
            self._score_published()
        self.run.flush()  # what is scored is on disk before the world may move on: a crash loses only what is not
        self._ack_pub.put(m.encode(m.GroundStationAck(self._ack.sent())))

    def _stream_passed(self, arrival: Arrival, due_us: int) -> bool:
        """A held frame comes out once its stream has delivered a frame stamped at or after its due
        time (zenoh keeps order within a key, so nothing earlier is still on its way), or once its
        vehicle has left. Release order then never depends on when frames arrived."""
        vid = arrival.item[0]
        return self.intake.stream_stamp_us.get(vid, -1) >= due_us or vid not in self.presence.active

    def completed(self, vid: int) -> bool:
        """A vehicle that acknowledged the final tick, or whose estimates reached the end of the run,
        left normally; otherwise it was lost."""
        if self.ended is not None and vid in self.ended.completed:
            return True
        return self.streams.latest_estimate_us.get(vid, -1) >= round(self.config.clock.duration_s * 1e6)

    def _score_published(self) -> None:
        self.run.write_scores(self.scorer.release(self._lockstep_watermark()))

    def _lockstep_watermark(self) -> int:
        """Estimates up to here can be scored in (time, vehicle) order (tick_ack.watermark_us)."""
        members = self.presence.active if self.tick_members is None else self.tick_members
        estimates, rejoined = self.streams.latest_estimate_us, self.presence.rejoined_us
        streams_us = {vid: max(estimates.get(vid, -1), rejoined.get(vid, -1)) for vid in members}
        return watermark_us(
            min(self.published_us, self.latest_truth_us), streams_us, self.intake.links.held_min_stamp()
        )

    def finish(self, status: str) -> dict:
        """Score everything left, write summary.json and timing.json, close the files
        (groundstation.run_end)."""
        return finish_run(self, status)
