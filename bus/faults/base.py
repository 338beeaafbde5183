"""What every fault kind shares (bus.faults): a name, a window of sim time, and what the kind declares
once so that everything else is derived from it:

- ``applied_by``: who applies it (``APPLIERS``: the world, every receiving bus layer, the supervisor,
  the vehicle's own outbound bus layer);
- ``effect``: one line for the docs' table (generated: docs/faults.md);
- ``marker``: the colour a zone of this kind is drawn with (the live view, the report), if any;
- ``chaos``: the parameters of one random fault of this kind for a chaos timeline (`swarm up --chaos`);
- per field, ``cli(...)``: its `swarm fault add` flag and how the flag's text is read (``READERS``).

A zone is a circle in the world's x-y plane (metres); a link fault selects traffic by source,
destination and topic globs. Times are sim seconds: a fault is active for
``start_s <= t < start_s + for_s`` (``for_s`` None: until the end of the run).
"""

from __future__ import annotations

import fnmatch
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from bus.sensors import BY_TOPIC
from bus.topics import Topic

GLOB = r"^[A-Za-z0-9_*?\[\]\-]{1,32}$"
NAME = r"^[A-Za-z0-9_.\-]{0,64}$"
LINK_TOPICS = (*Topic, *BY_TOPIC)  # the built-in feeds' topics and the added sensors' (bus.sensors)
APPLIERS = {
    "world": "the world",
    "link": "the receiving bus layer",
    "supervisor": "the supervisor (`swarm up`)",
    "outbound": "the vehicle's own outbound bus layer",
}
READERS = ("text", "float", "seconds", "metres", "percent", "xy", "vehicle", "vehicles")


def cli(flag: str, read: str = "float", example: str = "") -> dict[str, Any]:
    """A field's `swarm fault add` flag, how its text is read (one of ``READERS``), and an example."""
    assert read in READERS, read
    return {"flag": flag, "read": read, "example": example}


@dataclass(frozen=True)
class ChaosSwarm:
    """What a chaos timeline knows of the swarm its faults are drawn for."""

    vehicles: int
    extent_m: float  # the side of the square of start pads (zones are placed over it)


class FaultBase(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    applied_by: ClassVar[str] = "world"
    effect: ClassVar[str] = ""
    marker: ClassVar[tuple[float, float, float] | None] = None
    chaos_min_vehicles: ClassVar[int] = 1  # a chaos timeline has it only in swarms at least this large
    chaos_extra: ClassVar[bool] = True  # a chaos timeline may draw it again beyond its first
    chaos_lasts: ClassVar[bool] = True  # a chaos fault of this kind ends inside the run (for_s drawn)

    name: str = Field(
        "", pattern=NAME, description="unique label; assigned when empty", json_schema_extra=cli("--name", "text")
    )
    start_s: float = Field(
        0.0,
        ge=0,
        le=1e7,
        description="when it starts (sim s; `swarm fault add --in`: from now)",
        json_schema_extra=cli("--in", "seconds", "10s"),
    )
    for_s: float | None = Field(
        None,
        gt=0,
        le=1e7,
        description="how long it lasts (none: to the end of the run)",
        json_schema_extra=cli("--for", "seconds", "60s"),
    )

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s and (self.for_s is None or t_s < self.start_s + self.for_s)

    @classmethod
    def kind_name(cls) -> str:
        return cls.model_fields["kind"].default

    @classmethod
    def chaos(cls, rng: np.random.Generator, swarm: ChaosSwarm) -> dict[str, Any]:
        """The parameters of one random fault of this kind (no name, start or length)."""
        raise NotImplementedError(f"{cls.kind_name()} has no chaos entry")

    # what the world asks of a physical fault (sim.physical_faults); none by default
    def silences(self, vehicle_id: int, sensor: str, xy_m: np.ndarray) -> bool:
        """True when this (active) fault keeps ``sensor`` of vehicle ``vehicle_id`` at ``xy_m`` silent."""
        return False

    def jams_comms(self, xy_m: np.ndarray) -> bool:
        """True when this (active) fault cuts the radio of a vehicle at ``xy_m``."""
        return False


class Zone(FaultBase):
    center_m: tuple[float, float] = Field(
        description="zone centre [x, y] (m)", json_schema_extra=cli("--center", "xy", "40,10")
    )
    radius_m: float = Field(
        gt=0, le=1e6, description="zone radius (m)", json_schema_extra=cli("--radius", "metres", "25m")
    )

    def inside(self, xy_m: np.ndarray) -> bool:
        return bool(np.hypot(xy_m[0] - self.center_m[0], xy_m[1] - self.center_m[1]) <= self.radius_m)

    def zone(self) -> dict:
        return {"center_m": list(self.center_m), "radius_m": self.radius_m}

    @classmethod
    def chaos(cls, rng: np.random.Generator, swarm: ChaosSwarm) -> dict[str, Any]:
        return {
            "center_m": [round(float(c), 1) for c in rng.uniform(0, swarm.extent_m, 2)],
            "radius_m": round(float(rng.uniform(20, 50)), 1),
        }


class LinkFault(FaultBase):
    """Selects traffic by source, destination and topic (globs: ``v*``, ``v3``, ``gs``, ``mavlink``)."""

    applied_by: ClassVar[str] = "link"

    src: str = Field(
        "*", pattern=GLOB, description="sending endpoint glob", json_schema_extra=cli("--from", "text", "v2")
    )
    dst: str = Field(
        "*", pattern=GLOB, description="receiving endpoint glob", json_schema_extra=cli("--to", "text", "'v*'")
    )
    topic: str = Field(
        "*",
        pattern=GLOB,
        description="topic glob: imu, odom, gnss, ranging, mavlink, ...",
        json_schema_extra=cli("--topic", "text", "mavlink"),
    )

    def selects(self, src: str, dst: str, topic: str) -> bool:
        return (
            fnmatch.fnmatchcase(src, self.src)
            and fnmatch.fnmatchcase(dst, self.dst)
            and fnmatch.fnmatchcase(topic, self.topic)
        )

    @classmethod
    def chaos(cls, rng: np.random.Generator, swarm: ChaosSwarm) -> dict[str, Any]:
        dst = str(rng.choice(["v*", "gs", f"v{rng.integers(1, swarm.vehicles + 1)}"]))
        topic = (
            "mavlink"
            if dst == "gs"
            else str(rng.choice(["*", *map(str, (Topic.IMU, Topic.ODOM, Topic.GNSS, Topic.RANGING, Topic.MAVLINK))]))
        )
        return {"dst": dst, "topic": topic, **cls.chaos_parameters(rng)}

    @classmethod
    def chaos_parameters(cls, rng: np.random.Generator) -> dict[str, Any]:
        """The kind's own parameters of a random link fault."""
        raise NotImplementedError


def vehicle_field(**kwargs: Any) -> Any:
    """The field naming the vehicle a fault acts on (``--vehicle v3``)."""
    return Field(
        ge=1,
        le=250,
        description="the vehicle it acts on",
        json_schema_extra=cli("--vehicle", "vehicle", "v3"),
        **kwargs,
    )


def heading_field() -> Any:
    """The field giving the direction a false offset grows in (``--heading 90``)."""
    return Field(
        0.0,
        ge=-360,
        le=360,
        description="direction of the growth (deg, 0 = +x)",
        json_schema_extra=cli("--heading", "float", "90"),
    )
