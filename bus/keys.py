"""Every zenoh key expression swarmloc uses is built here, and nowhere else.

Layout under a configurable prefix (default ``swarm``)::

    <prefix>/v/<id>/sensor/<topic>   sensor feeds (imu, odom, gnss, prior, ...)
    <prefix>/v/<id>/truth            ground truth (world and ground station only)
    <prefix>/v/<id>/mavlink          MAVLink 2 state packets (every cycle; the ground station's feed)
    <prefix>/v/<id>/v2v              the V2V broadcast: ODOMETRY at the ranging epochs, for neighbours
    <prefix>/v/<id>/status           vehicle loop statistics
    <prefix>/ctl/clock               simulation clock ticks
    <prefix>/ctl/ack/<id>            lockstep acknowledgements
    <prefix>/ctl/end                 end of run
    <prefix>/ctl/faults/plan         the fault plan (published by the ground station only)
    <prefix>/ctl/faults/request      queryable of the ground station: add, remove, clear, list faults
    <prefix>/ctl/claim               queryable of the ground station: vehicle ids for `--id auto`
    <prefix>/alive/<role>/<id>       liveliness tokens
"""

from __future__ import annotations

from dataclasses import dataclass

SENSOR_TOPICS = ("imu", "odom", "gnss", "prior", "camera", "ranging", "landmarks")
ROLES = ("world", "vehicle", "groundstation", "router", "cli", "supervisor")


@dataclass(frozen=True)
class KeySpace:
    """Builds and parses the key expressions of one swarm (one prefix)."""

    prefix: str = "swarm"

    def sensor(self, vehicle_id: int | str, topic: str) -> str:
        if topic not in SENSOR_TOPICS:
            raise ValueError(f"unknown sensor topic {topic!r}; known: {', '.join(SENSOR_TOPICS)}")
        return f"{self.prefix}/v/{vehicle_id}/sensor/{topic}"

    def sensors(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/sensor/*"

    def truth(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/truth"

    def mavlink(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/mavlink"

    def v2v(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/v2v"

    def status(self, vehicle_id: int | str) -> str:
        return f"{self.prefix}/v/{vehicle_id}/status"

    def clock(self) -> str:
        return f"{self.prefix}/ctl/clock"

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
        if role not in ROLES:
            raise ValueError(f"unknown role {role!r}; known: {', '.join(ROLES)}")
        return f"{self.prefix}/alive/{role}/{ident}"

    def is_truth(self, key_expr: str) -> bool:
        """True when ``key_expr`` may match a truth key (wildcards included)."""
        parts = key_expr.split("/")
        prefix_parts = self.prefix.split("/")
        if parts[: len(prefix_parts)] != prefix_parts and not key_expr.startswith("**"):
            return False
        tail = parts[len(prefix_parts):] if parts[: len(prefix_parts)] == prefix_parts else parts
        if "**" in tail:
            return True
        return len(tail) == 3 and tail[0] in ("v", "*") and tail[2] in ("truth", "*")

    def vehicle_of(self, key: str) -> int:
        """The vehicle id inside a concrete ``<prefix>/v/<id>/...`` key."""
        parts = key[len(self.prefix) + 1:].split("/")
        if len(parts) < 2 or parts[0] != "v" or not parts[1].isdigit():
            raise ValueError(f"not a vehicle key: {key!r}")
        return int(parts[1])

    def topic_of(self, key: str) -> str:
        """The last segment of a concrete key: ``imu``, ``truth``, ``mavlink``, ..."""
        return key.rsplit("/", 1)[-1]
