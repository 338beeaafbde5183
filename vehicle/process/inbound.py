"""A vehicle process's bus layer: everything that arrives is parsed here (totally: any key, any
bytes), passed through the link faults of the fault plan, and only then handed to the estimator side.
Comm jamming is the world's: it makes no ranging to or from a jammed vehicle, the one thing a lost
broadcast would have spoilt.
"""

from __future__ import annotations

import logging
from collections import deque
from dataclasses import dataclass
from enum import Enum
from typing import Any

from bus import feed
from bus import messages as m
from bus.errors import DecodeError
from bus.faults import Accuse, Lie
from bus.keys import KeySpace, ParsedKey
from bus.link_faults import Arrival, LinkFaultStage
from bus.mailbox import Oversized
from bus.mavlink_codec import MAX_V2V_BYTES, frame_header
from bus.plan import FaultPlan, decode_json
from bus.rejections import Rejections
from bus.session import Envelope
from bus.topics import Topic

log = logging.getLogger("swarmloc.vehicle")
ODOMETRY_ID = 331  # MAVLINK_MSG_ID_ODOMETRY: the V2V packet
MAX_BATCH_BYTES = 1 << 20
MAX_CLOCK_BYTES = 8 << 10
MAX_PLAN_BYTES = 1 << 20
MAX_PARSED_KEYS = 4096  # the keys whose parse is remembered (a swarm has a few per vehicle)
LISTENER_BATCHES = 8  # the batches whose listeners are kept (a realtime cycle runs within a tick or two of its batch)


class Kind(Enum):
    """What a delivery carries."""

    SAMPLE = "sample"  # a sensor sample: ``topic`` and the message as ``payload``
    V2V = "v2v"  # a neighbour's ODOMETRY frame: ``payload`` = (sender, stamp us, frame bytes)
    TICK = "tick"  # a ClockTick
    HELD = "held"  # a sample of ``topic`` stamped ``stamp_us`` is held back by a link fault
    BATCH = "batch"  # a whole SensorBatch (``payload``) no link fault touches: its samples in its order


@dataclass(frozen=True)
class Delivery:
    """What the bus layer hands on (see ``Kind``)."""

    kind: Kind
    topic: Topic | None = None
    payload: Any = None
    stamp_us: int = 0


_V2V_FRAME = "v2v frame"  # marks a neighbour's frame among the samples inside the link-fault stage


class Inbound:
    def __init__(
        self, *, keys: KeySpace, vehicle_id: int, vehicles: int, fault_seed: int, faults: tuple, rejections: Rejections
    ) -> None:
        self.keys, self.vehicle_id, self.vehicles, self.rejections = keys, vehicle_id, vehicles, rejections
        self.links = LinkFaultStage(f"v{vehicle_id}", seed=fault_seed, faults=faults)
        self.behaviour = _own_behaviour(
            faults, vehicle_id
        )  # the plan's lies and accusations of it (vehicle.process.lies)
        self.plan_version = -1
        self.run_end: m.RunEnd | None = None  # the world has ended the run (vehicle.process.loops.hand_over_end)
        self.received_tick = -1  # the newest sensor batch that arrived
        self.refused_since = 0  # batches on its feed refused since the newest that arrived
        self.received_stamp_us = -1  # and the end of the time it covers
        self.heard: dict[int, int] = {}  # V2V frames sent to every vehicle heard, per sender
        self.v2v_received = 0  # every V2V frame the bus delivered, to this vehicle or not, valid or not
        self.heard_until: dict[int, int] = {}  # the newest stamp heard per sender (before link faults)
        self._listeners: deque[tuple[int, tuple[int, ...]]] = deque(maxlen=LISTENER_BATCHES)
        self._parsed: dict[str, ParsedKey] = {}  # keys seen, as KeySpace.parse read them
        self._control = {
            keys.clock(): self._clock,
            keys.pace(): self._clock,
            keys.fault_plan(): self._plan,
            keys.end(): self._end,
        }

    def take(self, item: Any) -> list[Delivery]:
        """File one mailbox item; returns what passes on (possibly nothing)."""
        if isinstance(item, Oversized):
            self.rejections.reject("oversized", item.key, f"{item.size} bytes")
            if item.key == self.keys.feed(self.vehicle_id):
                self.refused_since += 1
            return []
        if not isinstance(item, Envelope):
            self.rejections.reject("unexpected", "mailbox", type(item).__name__)
            return []
        control = self._control.get(item.key) if isinstance(item.key, str) else None
        if control is not None:  # the clock, the fault plan, the run's end
            return control(item)
        parsed = self._parsed.get(item.key) if isinstance(item.key, str) else None
        if parsed is None:
            parsed = self.keys.parse(item.key)
            if parsed is not None and len(self._parsed) < MAX_PARSED_KEYS:  # bounded against a flood of made-up keys
                self._parsed[item.key] = parsed
        if parsed is None or parsed.kind != "vehicle":
            self.rejections.reject("bad_key", "subscription", repr(item.key))
            return []
        if parsed.vehicle_id > self.vehicles:
            self.rejections.reject("unknown_vehicle", item.key, f"the swarm has {self.vehicles} vehicles")
            return []
        if parsed.topic == "feed" and parsed.vehicle_id == self.vehicle_id:
            return self._batch(item)
        self.v2v_received += parsed.topic == "v2v" and parsed.vehicle_id != self.vehicle_id
        if parsed.topic == "v2v" and parsed.recipient not in (None, self.vehicle_id):
            self.rejections.reject("unexpected", item.key, "a V2V frame addressed to another vehicle")
            return []
        if parsed.topic == "v2v" and parsed.vehicle_id != self.vehicle_id:
            return self._v2v(item, parsed.vehicle_id, to_all=parsed.recipient is None)
        if parsed.topic == "v2v":
            return []  # our own broadcast
        self.rejections.reject("unexpected", item.key, "not a key this vehicle listens to")
        return []

    def listeners_at(self, t_us: int) -> tuple[int, ...] | None:
        """Who the V2V broadcast of the cycle at ``t_us`` goes to: the listeners of the sensor batch
        that covers it (bus.feed.SensorBatch), or None (every vehicle) when no batch named them: a
        lockstep or replayed run, or a realtime cycle whose batch is late (a batch covers the time
        since the one before it)."""
        before, covering = -1, None
        for stamp_us, listeners in sorted(self._listeners):
            if stamp_us < t_us:
                before = stamp_us
            elif covering is None:
                covering = listeners
        return covering if covering is not None and before >= 0 else None

    def _clock(self, item: Envelope) -> list[Delivery]:
        try:
            tick = m.decode(m.ClockTick, item.payload)
        except DecodeError as exc:
            self.rejections.reject("malformed", item.key, str(exc))
            return []
        return [Delivery(Kind.TICK, payload=tick)]

    def _plan(self, item: Envelope) -> list[Delivery]:
        try:
            plan = decode_json(FaultPlan, item.payload)
        except DecodeError as exc:
            self.rejections.reject("malformed", item.key, str(exc))
            return []
        if plan.version > self.plan_version:
            self.plan_version = plan.version
            self.links.set_plan(plan.faults)
            self.behaviour = _own_behaviour(plan.faults, self.vehicle_id)
        return []

    def _end(self, item: Envelope) -> list[Delivery]:
        try:
            self.run_end = m.decode(m.RunEnd, item.payload)
        except DecodeError as exc:
            self.rejections.reject("malformed", item.key, str(exc))
        return []

    def _batch(self, item: Envelope) -> list[Delivery]:
        try:
            batch = feed.decode_batch(item.payload)
        except DecodeError as exc:
            self.rejections.reject("malformed", item.key, str(exc))
            self.refused_since += 1
            return []
        if batch.vehicle_id != self.vehicle_id:
            self.rejections.reject("impersonation", item.key, f"batch names vehicle {batch.vehicle_id}")
            self.refused_since += 1
            return []
        self.received_tick, self.refused_since = max(self.received_tick, batch.tick), 0
        self.received_stamp_us = max(self.received_stamp_us, batch.stamp_us)
        if batch.listeners is not None:
            self._listeners.append((batch.stamp_us, batch.listeners))
        if self.links.untouched(item.key, batch.count()):
            return [Delivery(Kind.BATCH, payload=batch)]
        out = []
        for topic, msg in batch.samples():
            arrival = Arrival(item.key, f"v{self.vehicle_id}", topic, msg.stamp_us, (topic, msg))
            out += self._offer(arrival)
        return out

    def _offer(self, arrival: Arrival) -> list[Delivery]:
        """Through the link faults: delivered now, or held (the fusion horizon is told to expect it)."""
        held, dropped = self.links.held, self.links.dropped_full
        passed = self.links.offer(arrival)
        if self.links.dropped_full > dropped:
            self.rejections.reject("held_full", arrival.key, "link-fault stage full")
        out = [self._delivery(p) for p in passed]
        if self.links.held > held:
            out.append(Delivery(Kind.HELD, arrival.topic, stamp_us=arrival.stamp_us))
        return out

    def _delivery(self, item: tuple[str, Any]) -> Delivery:
        topic, payload = item
        if topic == _V2V_FRAME:
            return Delivery(Kind.V2V, payload=payload, stamp_us=payload[1])
        return Delivery(Kind.SAMPLE, topic, payload, payload.stamp_us)

    def _v2v(self, item: Envelope, sender: int, *, to_all: bool) -> list[Delivery]:
        """A neighbour's ODOMETRY frame: counted as heard (``heard``: the frames sent to every vehicle,
        which lockstep's barrier counts), then through link faults."""
        frame = item.payload
        header = frame_header(frame) if len(frame) <= MAX_V2V_BYTES else None
        if header is None or header[2] != ODOMETRY_ID or header[3] is None:
            self.rejections.reject("malformed" if header is None else "unexpected", item.key, "not an ODOMETRY frame")
            return []
        if header[0] != sender:
            self.rejections.reject("impersonation", item.key, f"frame from sysid {header[0]}")
            return []
        if to_all:
            self.heard[sender] = self.heard.get(sender, 0) + 1
        stamp = header[3]
        self.heard_until[sender] = max(stamp, self.heard_until.get(sender, -1))
        heard = (_V2V_FRAME, (sender, stamp, frame))
        if self.links.untouched(item.key):
            return [self._delivery(heard)]
        return self._offer(Arrival(item.key, f"v{sender}", Topic.MAVLINK, stamp, heard))

    def release(self, now_us: int) -> list[Delivery]:
        """Held packets due by ``now_us``."""
        return [self._delivery(p) for p in self.links.release(now_us)]


def _own_behaviour(faults: tuple, vehicle_id: int) -> tuple[Lie | Accuse, ...]:
    return tuple(f for f in faults if isinstance(f, (Lie, Accuse)) and f.vehicle == vehicle_id)
