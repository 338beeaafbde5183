"""The run as Foxglove and Lichtblick see it: ``run.mcap`` in the run directory and, with ``--live``, a
Foxglove WebSocket server, both fed from the one place that may see truth (the ground station's
scores and events) through the Foxglove SDK, on a context of their own (no global state).

Its channels (log times are sim time, nanoseconds from the run's start) are listed once, in the
table of docs/live-view.md: the scene (poses, 3-sigma ellipses, trails, landmarks, fault zones,
ranging lines, the terrain under a camera swarm), the events, and per vehicle its estimate, truth,
metrics, GNSS health and loop statistics.

The per-vehicle JSON channels are topics of their own rather than one topic with a vehicle field:
a plot's legend shows a series' current value from the latest message of its topic, so a series
filtered out of a shared topic (``/health{vehicle==2}``) shows none whenever another vehicle spoke
last.

Every channel stays under 60 messages per second of sim time for swarms of up to 60 vehicles (the
viewers warn of "high frequency topics" above that). The live server has the WebSocket protocol's
time capability and broadcasts the sim time, so a viewer's clock and its plots' receive times are
the run's.

A live viewer gets its own bounded queue (``view.live_backlog`` messages, the SDK's): when a slow
viewer lets it fill, the oldest messages are dropped, never the run stalled; the SDK reports each
time a viewer's queue overflows, and the ground station logs it as a ``live_view_overflow`` event
(counted in summary.json).

A restarted ground station cannot append to an MCAP file: it records to ``run.1.mcap`` and so on.
"""

from __future__ import annotations

import json
import logging
import threading
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np

from groundstation import scene_entities as se
from groundstation import scene_primitives as sp
from groundstation.live_server import SDK_OVERFLOW_LOGGER, OverflowCounter, terrain_requests
from groundstation.plot_records import (
    HEALTH_SCHEMA,
    LOOP_SCHEMA,
    METRICS_SCHEMA,
    SWARM_SCHEMA,
    health_record,
    loop_record,
    metrics_record,
    nees_band_3dof,
    swarm_records,
)
from groundstation.scoring import Score

log = logging.getLogger("swarmloc.groundstation")
RANGING_STEP_US, SCENE_STEP_US, CLOCK_STEP_US = 200_000, 100_000, 100_000
TRAIL_S, TRAIL_STEP_US = 30, 1_000_000  # trails: the last 30 s, a point a second
MAP_STEP_US = 1_000_000  # the maps: every vehicle's newest, together, at most once a second
WARNING_EVENTS = ("fault", "neighbour_distrusted", "accusation_contradicted", "vehicle_lost", "estimator_reset", "gnss")


VEHICLE_TOPICS = ("estimate", "truth", "metrics", "health", "loop")


def pose_topic(vehicle_id: int, kind: str) -> str:
    """The Foxglove topic of a vehicle's ``kind`` (estimate, truth, metrics, health, loop; not a
    zenoh key)."""
    return f"/vehicle/{vehicle_id}/{kind}"


class Recording:
    """Writes the channels (module docstring) to an MCAP file and, once ``serve`` is called, to a
    WebSocket server too."""

    def __init__(self, path: Path | None, vehicles: int = 0) -> None:
        import foxglove
        from foxglove.channels import LogChannel, SceneUpdateChannel

        self._foxglove = foxglove
        self.context = foxglove.Context()
        self.path = path
        self.writer = foxglove.open_mcap(path, context=self.context) if path is not None else None
        self.server = None
        self.scene = SceneUpdateChannel("/scene", context=self.context)
        self.events = LogChannel("/events", context=self.context)
        self.zone_scene = SceneUpdateChannel("/zones", context=self.context)
        self.landmark_scene = SceneUpdateChannel("/landmarks", context=self.context)
        self.ranging_scene = SceneUpdateChannel("/ranging", context=self.context)
        self.terrain_scene = SceneUpdateChannel("/terrain", context=self.context)
        self.swarm_channel = foxglove.Channel("/swarm", schema=SWARM_SCHEMA, context=self.context)
        self._poses: dict[tuple[str, int], Any] = {}
        self._scene: dict[int, Score] = {}  # vehicle -> its latest score, not in the scene yet
        self._scene_us = self._ranging_us = self._clock_us = self._maps_us = -(2**62)  # when each was last logged
        self._maps: dict[int, Any] = {}  # vehicle -> its newest map (bus.landmark_map.LandmarkMap)
        self._zones: set[str] = set()
        self._terrain: bytes | None = None
        self._terrain_wanted = threading.Event()  # a live viewer subscribed to /terrain (SDK thread)
        self._overflows = OverflowCounter()
        self._last_ns = 0
        self._nees_band = nees_band_3dof()
        self.trail_scene = SceneUpdateChannel("/trails", context=self.context)
        self._trails: dict[int, deque] = {}  # vehicle -> (stamp us, true xy, estimated xy), one a second
        for vid in range(1, vehicles + 1):  # advertised at once: a viewer sees every topic from the start
            for kind in VEHICLE_TOPICS:
                self._pose_channel(kind, vid)

    def serve(self, host: str, port: int, backlog: int = 1024) -> None:
        """Start the live view (a Foxglove WebSocket server on ``host``:``port``), each viewer's queue
        bounded to ``backlog`` messages."""
        sdk_log = logging.getLogger(SDK_OVERFLOW_LOGGER)
        sdk_log.setLevel(logging.INFO)  # the SDK reports an overflow at INFO
        sdk_log.addHandler(self._overflows)
        from foxglove.websocket import Capability

        self.server = self._foxglove.start_server(
            name="swarmloc",
            host=host,
            port=port,
            context=self.context,
            capabilities=[Capability.Time],
            message_backlog_size=backlog,
            server_listener=terrain_requests(self._terrain_wanted),
        )

    def overflows(self) -> int:
        """How many times a live viewer's queue overflowed since the last call (the SDK's reports)."""
        return self._overflows.take()

    def terrain(self, glb: bytes) -> None:
        """The terrain model (a GLB, groundstation.terrain_model) under the scene, logged now."""
        self._terrain = glb
        self._log_terrain()

    def _log_terrain(self) -> None:
        from foxglove import messages as fm

        update = se.terrain_update(fm, self._terrain, self._last_ns // 1000)
        self.terrain_scene.log(update, log_time=self._last_ns)

    def _serve_requests(self) -> None:
        """Log the terrain again for a viewer that subscribed since (the live view keeps nothing)."""
        if self._terrain is not None and self._terrain_wanted.is_set():
            self._terrain_wanted.clear()
            self._log_terrain()

    def _clock(self, stamp_us: int) -> None:
        """The run has reached ``stamp_us``: a live viewer's clock follows, every CLOCK_STEP_US."""
        self._last_ns = max(self._last_ns, stamp_us * 1000)
        if self.server is not None and stamp_us >= self._clock_us + CLOCK_STEP_US:
            self._clock_us = stamp_us
            self.server.broadcast_time(stamp_us * 1000)

    def ranging(self, stamp_us: int, pairs: np.ndarray, positions: dict[int, np.ndarray]) -> None:
        """Lines between the ``positions`` (vehicle id -> (2,) m) of each ranging pair (m, 2) of a
        tick, at most every RANGING_STEP_US."""
        from foxglove import messages as fm

        self._clock(stamp_us)
        if stamp_us < self._ranging_us + RANGING_STEP_US:
            self._serve_requests()
            return
        self._ranging_us = stamp_us
        self.ranging_scene.log(se.ranging_update(fm, stamp_us, pairs, positions), log_time=stamp_us * 1000)
        self._serve_requests()

    def health(self, status: Any) -> None:
        """One vehicle's GNSS health (a bus.mavlink_codec.EstimatorStatus)."""
        channel = self._pose_channel("health", status.vehicle_id)
        channel.log(health_record(status), log_time=max(status.time_usec, 0) * 1000)

    def loop(self, status: Any) -> None:
        """One vehicle's loop statistics (a bus.messages.VehicleStatus)."""
        self._pose_channel("loop", status.vehicle_id).log(loop_record(status), log_time=max(status.stamp_us, 0) * 1000)

    def _pose_channel(self, kind: str, vehicle_id: int):
        """A vehicle's channel: its ``estimate`` or ``truth`` poses, or its ``metrics``, ``health`` or
        ``loop`` records (three lookups a score: the import only where a channel is made)."""
        key = (kind, vehicle_id)
        if key not in self._poses:
            from foxglove.channels import PoseInFrameChannel

            topic = pose_topic(vehicle_id, kind)
            schema = {"metrics": METRICS_SCHEMA, "health": HEALTH_SCHEMA, "loop": LOOP_SCHEMA}.get(kind)
            self._poses[key] = (
                PoseInFrameChannel(topic, context=self.context)
                if schema is None
                else self._foxglove.Channel(topic, schema=schema, context=self.context)
            )
        return self._poses[key]

    def scores(self, scores: list[Score]) -> None:
        from foxglove import messages as fm

        for s in scores:
            ns = s.stamp_us * 1000
            stamp = sp.stamp(fm, s.stamp_us)
            est, truth = s.estimate, s.truth_pose
            est_z, true_z = se.heights_m(s)
            estimate_pose = sp.pose(fm, est.position_m[0], est.position_m[1], est.yaw_rad, est_z)
            true_pose = sp.pose(fm, truth[0], truth[1], truth[2], true_z)
            self._pose_channel("estimate", s.vehicle_id).log(
                fm.PoseInFrame(timestamp=stamp, frame_id="world", pose=estimate_pose), log_time=ns
            )
            self._pose_channel("truth", s.vehicle_id).log(
                fm.PoseInFrame(timestamp=stamp, frame_id="world", pose=true_pose), log_time=ns
            )
            self._scene[s.vehicle_id] = s
            self._pose_channel("metrics", s.vehicle_id).log(metrics_record(s, self._nees_band), log_time=ns)
        if scores:
            self._clock(scores[-1].stamp_us)
            if scores[-1].stamp_us >= self._scene_us + SCENE_STEP_US:
                self._log_scene(scores[-1].stamp_us)
        self._log_trails(scores)
        for stamp_us, record in swarm_records(scores):
            self.swarm_channel.log(record, log_time=stamp_us * 1000)

    def _log_scene(self, stamp_us: int) -> None:
        """Each vehicle's latest pose arrows and ellipse, in one update."""
        from foxglove import messages as fm

        if self._scene:
            entities = [se.vehicle_entity(fm, s) for s in self._scene.values()]
            self.scene.log(fm.SceneUpdate(entities=entities), log_time=stamp_us * 1000)
            self._scene, self._scene_us = {}, stamp_us

    def _log_trails(self, scores: list[Score]) -> None:
        """Each vehicle's true and estimated trail (the last TRAIL_S, a point a second), logged when a
        vehicle's trail gains a point: one entity per vehicle, so a recording scrubs to a full trail."""
        from foxglove import messages as fm

        grown: dict[int, int] = {}
        for s in scores:
            trail = self._trails.setdefault(s.vehicle_id, deque())
            if trail and s.stamp_us < trail[-1][0] + TRAIL_STEP_US:
                continue
            est_z, true_z = se.heights_m(s)
            trail.append((s.stamp_us, (*s.truth_pose[:2], true_z), (*s.estimate.position_m[:2], est_z)))
            while trail[0][0] < s.stamp_us - TRAIL_S * 1_000_000:
                trail.popleft()
            grown[s.vehicle_id] = s.stamp_us
        entities = [se.trail_entity(fm, vid, stamp_us, self._trails[vid]) for vid, stamp_us in grown.items()]
        if entities:
            self.trail_scene.log(fm.SceneUpdate(entities=entities), log_time=max(grown.values()) * 1000)

    def landmarks(self, lmap: Any) -> None:
        """A SLAM vehicle's map (bus.landmark_map.LandmarkMap): kept as its newest, and every vehicle's
        newest logged together at most once per MAP_STEP_US of sim time (``_log_maps``)."""
        self._maps[lmap.vehicle_id] = lmap
        if lmap.stamp_us >= self._maps_us + MAP_STEP_US:
            self._log_maps(lmap.stamp_us)

    def _log_maps(self, stamp_us: int) -> None:
        """Every vehicle's newest map in one update: a viewer seeking in the recording shows the newest
        message of /landmarks, which then holds them all."""
        from foxglove import messages as fm

        if self._maps:
            update = se.landmark_update(fm, [self._maps[vid] for vid in sorted(self._maps)])
            self.landmark_scene.log(update, log_time=max(stamp_us, 0) * 1000)
        self._maps_us = stamp_us

    def zones(self, stamp_us: int, faults: list) -> None:
        """Draw the fault zones active at ``stamp_us`` and delete those that ended (only on a change)."""
        from foxglove import messages as fm

        t_s = stamp_us * 1e-6
        active = {f.name: f for f in faults if hasattr(f, "radius_m") and f.active(t_s)}
        if set(active) == self._zones:
            return
        update = se.zone_update(fm, stamp_us, active, self._zones - set(active))
        self.zone_scene.log(update, log_time=stamp_us * 1000)
        self._zones = set(active)

    def event(self, record: dict[str, Any], stamp_us: int) -> None:
        from foxglove import messages as fm

        kind = str(record.get("event", ""))
        level = fm.LogLevel.Warning if any(w in kind for w in WARNING_EVENTS) else fm.LogLevel.Info
        stamp = sp.stamp(fm, stamp_us)
        self.events.log(
            fm.Log(timestamp=stamp, level=level, message=json.dumps(record, sort_keys=True), name="groundstation"),
            log_time=max(stamp_us, 0) * 1000,
        )

    def message(self, stamp_us: int, text: str, warning: bool = True, name: str = "groundstation") -> None:
        """A log message on /events that is not a run event (rejected input, first of each kind)."""
        from foxglove import messages as fm

        level = fm.LogLevel.Warning if warning else fm.LogLevel.Info
        self.events.log(
            fm.Log(timestamp=sp.stamp(fm, max(stamp_us, 0)), level=level, message=text, name=name),
            log_time=max(stamp_us, 0) * 1000,
        )

    def close(self) -> None:
        """Finish the MCAP file (its index and footer) and stop the server."""
        self._log_scene(self._last_ns // 1000)
        if self._maps:
            self._log_maps(max(m.stamp_us for m in self._maps.values()))
        if self.writer is not None:
            self.writer.close()
            self.writer = None
        if self.server is not None:
            self.server.stop()
            self.server = None
            logging.getLogger(SDK_OVERFLOW_LOGGER).removeHandler(self._overflows)
