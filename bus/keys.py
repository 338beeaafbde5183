"""Every zenoh key expression swarmloc uses is built here, and nowhere else; and every key that
arrives is parsed here, totally (any string gives a ParsedKey or None, never an exception).

Layout under a configurable prefix (default ``swarm``)::

    <prefix>/v/<id>/feed             the world's sensor batch for one vehicle, one per clock tick
    <prefix>/v/<id>/mavlink          MAVLink 2 frames of one vehicle (the ground station's feed)
    <prefix>/v/<id>/v2v              the V2V broadcast: ODOMETRY at the ranging epochs, for neighbours
    <prefix>/v/<id>/status           vehicle loop statistics
    <prefix>/truth                   ground truth of every vehicle, one batch per tick (world -> ground station)
    <prefix>/ctl/clock               simulation clock ticks
    <prefix>/ctl/pace                the ticks a realtime vehicle needs (the first two, one a second, the final)
    <prefix>/ctl/ack/<id>            lockstep acknowledgements of vehicle <id>; ``gs`` for the ground station
    <prefix>/ctl/end                 end of run
    <prefix>/ctl/faults/plan         the fault plan (published by the ground station only)
    <prefix>/ctl/faults/request      queryable of the ground station: add, remove, clear, list faults
    <prefix>/ctl/claim               queryable of the ground station: vehicle ids for `--id auto`
    <prefix>/alive/<role>/<id>       liveliness tokens

Vehicle ids on the wire are plain ASCII decimals 1-250 without leading zeros (``'²'.isdigit()`` is
true in Python; such a key is not a vehicle key).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

VEHICLE_TOPICS = ("feed", "mavlink", "v2v", "status")
ROLES = ("world", "vehicle", "groundstation", "router", "cli", "supervisor")
MAX_VEHICLE_ID = 250
_ID = re.compile(r"[1-9][0-9]{0,2}")
GS_ACK = "gs"


def parse_vehicle_id(text: str) -> int | None:
    """A vehicle id from its key segment: ASCII decimal 1-250, no sign, no leading zero; else None."""
    if not isinstance(text, str) or _ID.fullmatch(text) is None:
        return None
    value = int(text)
    return value if value <= MAX_VEHICLE_ID else None


@dataclass(frozen=True)
class ParsedKey:
    """What a concrete key names: ``kind`` (vehicle, truth, clock, pace, ack, end, plan, request, claim,
    alive), the vehicle id when there is one, the topic of a vehicle key, the role of a token, and
    the vehicle a V2V frame is addressed to (``recipient``; None: broadcast to all)."""

    kind: str
    vehicle_id: int | None = None
    topic: str | None = None
    role: str | None = None
    ident: str | None = None
    recipient: int | None = None


_CTL = {
    "clock": "clock",
    "pace": "pace",
    "end": "end",
    "faults/plan": "plan",
    "faults/request": "request",
    "claim": "claim",
}


@dataclass(frozen=True)
class KeySpace:
    """Builds and parses the key expressions of one swarm (one prefix)."""

    prefix: str = "swarm"

    def feed(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/feed"

    def truth(self) -> str:
        return f"{self.prefix}/truth"

    def mavlink(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/mavlink"

    def v2v(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/v2v"

    def v2v_to(self, vehicle_id: int | str, recipient: int | str) -> str:
        """Vehicle ``vehicle_id``'s V2V frames addressed to ``recipient`` only."""
        return f"{self.prefix}/v/{vehicle_id}/v2v/{recipient}"

    def status(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/status"

    def clock(self) -> str:
        return f"{self.prefix}/ctl/clock"

    def pace(self) -> str:
        return f"{self.prefix}/ctl/pace"

    def ack(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/ctl/ack/{vehicle_id}"

    def end(self) -> str:
        return f"{self.prefix}/ctl/end"

    def fault_plan(self) -> str:
        return f"{self.prefix}/ctl/faults/plan"

    def fault_request(self) -> str:
        return f"{self.prefix}/ctl/faults/request"

    def claim(self) -> str:
        return f"{self.prefix}/ctl/claim"

    def alive(self, role: str, ident: int | str) -> str:
        """A liveliness token; ``ident`` "*" matches every one of the role, "**" too (ACL rules)."""
        if role not in ROLES:
            raise ValueError(f"unknown role {role!r}; known: {', '.join(ROLES)}")
        return f"{self.prefix}/alive/{role}/{ident}"

    def every_token(self) -> str:
        """Every liveliness token of the swarm, of any role."""
        return f"{self.prefix}/alive/**"

    def under_vehicle(self, vehicle_id: int | str) -> str:
        """Every key of one vehicle (``v/<id>/**``: its MAVLink, V2V, status and feed)."""
        return f"{self.prefix}/v/{vehicle_id}/**"

    def every_fault_key(self) -> str:
        """The fault plan and the fault requests (``ctl/faults/**``)."""
        return f"{self.prefix}/ctl/faults/**"

    def is_truth(self, key_expr: str) -> bool:
        """True when ``key_expr`` may match the truth key (wildcards included)."""
        import zenoh

        try:
            return zenoh.KeyExpr(key_expr).intersects(zenoh.KeyExpr(self.truth()))
        except Exception:  # not a valid key expression: it cannot be subscribed to either
            return False

    def parse(self, key: str) -> ParsedKey | None:
        """What a concrete key names, or None when it is none of ours (total: never raises)."""
        if not isinstance(key, str) or not key.startswith(self.prefix + "/"):
            return None
        parts = key[len(self.prefix) + 1 :].split("/")
        head, rest = parts[0], parts[1:]
        if head == "v" and len(rest) == 2 and rest[1] in VEHICLE_TOPICS:
            vid = parse_vehicle_id(rest[0])
            return None if vid is None else ParsedKey("vehicle", vid, rest[1])
        if head == "v" and len(rest) == 3 and rest[1] == "v2v":
            vid, recipient = parse_vehicle_id(rest[0]), parse_vehicle_id(rest[2])
            return None if vid is None or recipient is None else ParsedKey("vehicle", vid, "v2v", recipient=recipient)
        if head == "truth" and not rest:
            return ParsedKey("truth")
        if head == "ctl" and len(rest) == 2 and rest[0] == "ack":
            if rest[1] == GS_ACK:
                return ParsedKey("ack", ident=GS_ACK)
            vid = parse_vehicle_id(rest[1])
            return None if vid is None else ParsedKey("ack", vid)
        if head == "ctl" and "/".join(rest) in _CTL:
            return ParsedKey(_CTL["/".join(rest)])
        if head == "alive" and len(rest) == 2 and rest[0] in ROLES:
            role, ident = rest
            if role == "vehicle":
                vid = parse_vehicle_id(ident)
                return None if vid is None else ParsedKey("alive", vid, role=role, ident=ident)
            return ParsedKey("alive", role=role, ident=ident) if ident.isascii() and ident.isalnum() else None
        return None

    def vehicle_of(self, key: str) -> int | None:
        """The vehicle id inside a concrete ``<prefix>/v/<id>/<topic>`` key, or None (total)."""
        parsed = self.parse(key)
        return parsed.vehicle_id if parsed is not None and parsed.kind == "vehicle" else None
