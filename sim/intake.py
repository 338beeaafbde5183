"""What the world hears: liveliness tokens, the fault plan and the tick acknowledgements, each checked
and filed where it belongs (who is there and who acknowledged: sim.membership; a newer fault plan:
handed to the world node). Anything that does not parse, or names someone it should not, is
rejected by reason and never counts for anyone."""

from __future__ import annotations

from collections.abc import Callable

from bus import messages as m
from bus.errors import DecodeError
from bus.mailbox import Mailbox, Oversized
from bus.plan import MAX_PLAN_BYTES, FaultPlan, decode_json
from bus.rejections import Rejections
from bus.session import Bus, Envelope, LivelinessEvent
from sim.membership import Membership

MAX_ACK_BYTES = 256


class WorldIntake:
    """The world's subscriptions and its mailbox: liveliness and the plan on one lane, the acks on
    another. ``on_plan`` is called with each fault plan newer than the last."""

    def __init__(
        self, bus: Bus, members: Membership, on_plan: Callable[[FaultPlan], None], rejections: Rejections
    ) -> None:
        self.keys, self.members, self.rejections, self._on_newer_plan = bus.keys, members, rejections, on_plan
        self.mailbox = Mailbox()
        control, acks = self.mailbox.lane("control", max_items=10_000), self.mailbox.lane("acks", max_items=100_000)
        bus.watch_liveliness(self.keys.every_token(), control)
        bus.subscribe(self.keys.fault_plan(), control, MAX_PLAN_BYTES)
        bus.subscribe(self.keys.ack("*"), acks, MAX_ACK_BYTES)
        self.plan_version = -1

    def drain(self, timeout_s: float, tick: int | None = None) -> None:
        """Handle mailbox items (liveliness, plan, acks of ``tick``) for up to ``timeout_s``."""
        item = self.mailbox.get(timeout_s)
        while item is not None:
            self.handle(item, tick)
            item = self.mailbox.get_nowait()

    def handle(self, item: object, tick: int | None) -> None:
        """File one mailbox item; an ack counts towards ``tick`` only if it is for that tick."""
        if isinstance(item, LivelinessEvent):
            parsed = self.keys.parse(item.key)
            if parsed is None or parsed.kind != "alive":
                self.rejections.reject("bad_key", "liveliness", repr(item.key))
            else:
                self.members.on_token(parsed.role, parsed.vehicle_id, item.alive)
        elif isinstance(item, Oversized):
            self.rejections.reject("oversized", item.key, f"{item.size} bytes")
        elif isinstance(item, Envelope) and item.key == self.keys.fault_plan():
            self._on_plan(item)
        elif isinstance(item, Envelope):
            self._on_ack(item, tick)

    def _on_plan(self, envelope: Envelope) -> None:
        try:
            plan = decode_json(FaultPlan, envelope.payload)
        except DecodeError as exc:
            self.rejections.reject("malformed", envelope.key, str(exc))
            return
        if plan.version > self.plan_version:
            self.plan_version = plan.version
            self._on_newer_plan(plan)

    def _on_ack(self, envelope: Envelope, tick: int | None) -> None:
        parsed = self.keys.parse(envelope.key)
        if parsed is None or parsed.kind != "ack":
            self.rejections.reject("bad_key", "acks", repr(envelope.key))
            return
        try:
            if parsed.ident == "gs":
                self.members.gs_acked = max(self.members.gs_acked, m.decode(m.GroundStationAck, envelope.payload).tick)
                return
            ack = m.decode(m.TickAck, envelope.payload)
        except DecodeError as exc:
            self.rejections.reject("malformed", envelope.key, str(exc))
            return
        if ack.vehicle_id != parsed.vehicle_id:
            self.rejections.reject("impersonation", envelope.key, f"ack names vehicle {ack.vehicle_id}")
            return
        if ack.vehicle_id not in self.members.expected:
            self.rejections.reject("unknown_vehicle", envelope.key, f"vehicle {ack.vehicle_id}")
            return
        self.members.on_v2v_count(ack.vehicle_id, ack.v2v_sent)
        if ack.vehicle_id in self.members.joining:
            # a restarted vehicle is in lockstep from its first ack, whichever tick it is for: one
            # that starts slower than the swarm acks ticks the world has left behind, and the clock
            # must wait for it to catch up, or it would never ack the current tick in time to join
            self.members.joining.discard(ack.vehicle_id)
            self.members.alive.add(ack.vehicle_id)
        if ack.tick == tick:
            self.members.acked.add(ack.vehicle_id)
