"""The fault plan: every fault the swarm can suffer, as validated models (pydantic).

Times are sim seconds. A fault is active for ``start_s <= t < start_s + for_s`` (``for_s`` None:
until the end of the run). Zones are circles in the world's x-y plane (metres).

- physical faults, applied by the world: ``jam-gnss``, ``spoof-gnss``, ``blackout``, ``jam-comms``;
- link faults, applied by each receiving process's bus layer (``bus.link_faults``): ``delay``,
  ``loss``, ``duplicate``, ``reorder``, selected by source, destination and topic globs;
- ``kill``: the vehicle process is SIGKILLed at ``start_s`` and, with ``restart_after_s``, started
  again by the supervisor (``swarm up``);
- ``lie``: a vehicle that lies to its neighbours, applied by the liar's own outbound bus layer to
  the V2V broadcasts it sends (its estimator and its MAVLink stream to the ground station stay
  honest, so the ground station scores what the lie does to the others);
- ``accuse``: a vehicle whose V2V broadcasts accuse the named vehicles, validly signed, whatever its
  own evidence (an insider turning the swarm against honest vehicles; docs/security.md), applied by
  its own outbound bus layer too.

Endpoints are named ``v<id>`` (vehicles), ``gs`` (ground station) and ``world``.
"""

from __future__ import annotations

import fnmatch
import re
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from bus.topics import Topic

GLOB = r"^[A-Za-z0-9_*?\[\]\-]{1,32}$"
NAME = r"^[A-Za-z0-9_.\-]{0,64}$"
LINK_TOPICS = tuple(Topic)


class _Fault(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field("", pattern=NAME, description="unique label; assigned when empty")
    start_s: float = Field(0.0, ge=0, le=1e7)
    for_s: float | None = Field(None, gt=0, le=1e7)

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s and (self.for_s is None or t_s < self.start_s + self.for_s)


class _Zone(_Fault):
    center_m: tuple[float, float] = Field(description="zone centre [x, y] (m)")
    radius_m: float = Field(gt=0, le=1e6)

    def inside(self, xy_m: np.ndarray) -> bool:
        return bool(np.hypot(xy_m[0] - self.center_m[0], xy_m[1] - self.center_m[1]) <= self.radius_m)

    def zone(self) -> dict:
        return {"center_m": list(self.center_m), "radius_m": self.radius_m}


class JamGnss(_Zone):
    """No GNSS fix for vehicles inside the zone."""

    kind: Literal["jam-gnss"] = "jam-gnss"


class SpoofGnss(_Zone):
    """Fixes inside the zone carry an offset growing at ``drift_mps`` along ``heading_deg`` (0 = +x)
    from the moment the vehicle is captured (enters the active zone)."""

    kind: Literal["spoof-gnss"] = "spoof-gnss"
    drift_mps: float = Field(0.5, gt=0, le=100)
    heading_deg: float = Field(0.0, ge=-360, le=360)


class JamComms(_Zone):
    """Vehicle-to-vehicle packets and ranging to and from vehicles inside the zone are lost."""

    kind: Literal["jam-comms"] = "jam-comms"


class Blackout(_Fault):
    """One sensor of one vehicle stays silent."""

    kind: Literal["blackout"] = "blackout"
    vehicle: int = Field(ge=1, le=250)
    sensor: Literal["imu", "odom", "gnss", "ranging", "landmark", "camera"]


class Kill(_Fault):
    """SIGKILL of a vehicle process at ``start_s``; restarted ``restart_after_s`` later (None: never)."""

    kind: Literal["kill"] = "kill"
    vehicle: int = Field(ge=1, le=250)
    restart_after_s: float | None = Field(None, ge=0, le=1e7)

    def kill_us(self) -> int:
        """Sim time [us] of the kill (the supervisor and the world compare the same integers)."""
        return round(self.start_s * 1e6)

    def restart_us(self) -> int | None:
        return None if self.restart_after_s is None else round((self.start_s + self.restart_after_s) * 1e6)


class Lie(_Fault):
    """Vehicle ``vehicle`` broadcasts its estimate of ``stale_s`` before (a replay of its own past,
    stamped now; 0: its present one), moved by ``offset_m`` plus an offset growing at ``drift_mps``
    along ``heading_deg`` (0 = +x) since ``start_s``, with its covariance times ``cov_scale`` (0.01:
    a hundred times too sure). Validly signed: it speaks only for itself."""

    kind: Literal["lie"] = "lie"
    vehicle: int = Field(ge=1, le=250)
    offset_m: tuple[float, float] = Field((0.0, 0.0), description="constant offset [x, y] (m)")
    drift_mps: float = Field(0.0, ge=0, le=100)
    heading_deg: float = Field(0.0, ge=-360, le=360)
    cov_scale: float = Field(1.0, gt=0, le=1e6)
    stale_s: float = Field(0.0, ge=0, le=60, description="broadcast the estimate of this long before")

    @model_validator(mode="after")
    def _says_something_false(self) -> Lie:
        if not (any(self.offset_m) or self.drift_mps or self.cov_scale != 1.0 or self.stale_s):
            raise ValueError("a lie needs --offset, --drift, --cov-scale or --stale: this one would tell the truth")
        if not all(abs(v) <= 1e6 for v in self.offset_m):
            raise ValueError("--offset: each coordinate must be within +-1e6 m")
        return self

    def offset_at(self, t_s: float) -> np.ndarray:
        """The position offset (2,) [m] the liar adds at sim time ``t_s`` (active or not)."""
        heading = np.radians(self.heading_deg)
        grown = self.drift_mps * max(0.0, t_s - self.start_s)
        return np.array(self.offset_m) + grown * np.array([np.cos(heading), np.sin(heading)])


class Accuse(_Fault):
    """Vehicle ``vehicle`` accuses ``names`` in every V2V broadcast (after whom its own monitor
    distrusts, at most 8 in all: bus.mavlink_codec.MAX_ACCUSED), validly signed."""

    kind: Literal["accuse"] = "accuse"
    vehicle: int = Field(ge=1, le=250)
    names: tuple[Annotated[int, Field(ge=1, le=250)], ...] = Field(
        min_length=1, max_length=8, description="the vehicles it accuses"
    )

    @model_validator(mode="after")
    def _accuses_others(self) -> Accuse:
        if self.vehicle in self.names:
            raise ValueError(f"--names: v{self.vehicle} would accuse itself")
        return self


class _LinkFault(_Fault):
    """Selects traffic by source, destination and topic (globs: ``v*``, ``v3``, ``gs``, ``mavlink``)."""

    src: str = Field("*", pattern=GLOB, description="sending endpoint glob")
    dst: str = Field("*", pattern=GLOB, description="receiving endpoint glob")
    topic: str = Field("*", pattern=GLOB, description="topic glob: imu, odom, gnss, ranging, mavlink, ...")

    def selects(self, src: str, dst: str, topic: str) -> bool:
        return (
            fnmatch.fnmatchcase(src, self.src)
            and fnmatch.fnmatchcase(dst, self.dst)
            and fnmatch.fnmatchcase(topic, self.topic)
        )


class Delay(_LinkFault):
    """Every selected packet is late by ``delay_s`` +- ``jitter_s`` (uniform, normal with sigma
    jitter_s, or pareto: heavy tail, minimum delay_s - jitter_s, mean delay_s). Jitter reorders."""

    kind: Literal["delay"] = "delay"
    delay_s: float = Field(ge=0, le=60)
    jitter_s: float = Field(0.0, ge=0, le=60)
    distribution: Literal["uniform", "normal", "pareto"] = "uniform"


class Loss(_LinkFault):
    """``percent`` of the selected packets are lost: independently, or with ``burst`` (mean burst
    length in packets) in Gilbert-Elliott bursts with the same long-run loss rate."""

    kind: Literal["loss"] = "loss"
    percent: float = Field(ge=0, le=100)
    burst: float | None = Field(None, ge=1, le=1e6)


class Duplicate(_LinkFault):
    """``percent`` of the selected packets arrive twice."""

    kind: Literal["duplicate"] = "duplicate"
    percent: float = Field(ge=0, le=100)


class Reorder(_LinkFault):
    """``percent`` of the selected packets are held back by ``gap_s`` so later ones overtake them."""

    kind: Literal["reorder"] = "reorder"
    percent: float = Field(ge=0, le=100)
    gap_s: float = Field(0.1, gt=0, le=60)


PHYSICAL_KINDS = ("jam-gnss", "spoof-gnss", "jam-comms", "blackout")
BEHAVIOUR_KINDS = ("lie", "accuse")
LINK_KINDS = ("delay", "loss", "duplicate", "reorder")
Fault = Annotated[
    JamGnss | SpoofGnss | JamComms | Blackout | Kill | Lie | Accuse | Delay | Loss | Duplicate | Reorder,
    Field(discriminator="kind"),
]


def endpoints(vehicles: int) -> list[str]:
    """Every endpoint name of a swarm of ``vehicles``: world, gs, v1 .. vN."""
    return ["world", "gs", *(f"v{i}" for i in range(1, vehicles + 1))]


def check_fault(fault: _Fault, vehicles: int) -> None:
    """Raise ValueError when ``fault`` names a vehicle or endpoint that is not in the swarm."""
    vehicle = getattr(fault, "vehicle", None)
    if vehicle is not None and vehicle > vehicles:
        raise ValueError(f"fault {fault.name or fault.kind}: vehicle {vehicle} does not exist ({vehicles} vehicles)")
    missing = [n for n in getattr(fault, "names", ()) if n > vehicles]
    if missing:
        raise ValueError(
            f"fault {fault.name or fault.kind}: --names v{missing[0]} does not exist ({vehicles} vehicles)"
        )
    if isinstance(fault, _LinkFault):
        names = endpoints(vehicles)
        for label, glob in (("--from", fault.src), ("--to", fault.dst)):
            if not any(fnmatch.fnmatchcase(n, glob) for n in names):
                hint = (
                    f"vehicles are v1..v{vehicles}" if re.fullmatch(r"v\d+", glob) else "endpoints are v<id>, gs, world"
                )
                raise ValueError(f"fault {fault.name or fault.kind}: {label} {glob!r} matches nothing ({hint})")
        if not any(fnmatch.fnmatchcase(t, fault.topic) for t in LINK_TOPICS):
            raise ValueError(
                f"fault {fault.name or fault.kind}: --topic {fault.topic!r} matches no topic ({', '.join(LINK_TOPICS)})"
            )


def named(faults: list, taken: set[str] | None = None) -> list:
    """The faults with empty names replaced by ``<kind>-<n>`` (first n not in ``taken`` or used)."""
    used = set(taken or ()) | {f.name for f in faults if f.name}
    out = []
    for fault in faults:
        if not fault.name:
            n = 1
            while f"{fault.kind}-{n}" in used:
                n += 1
            fault = fault.model_copy(update={"name": f"{fault.kind}-{n}"})
            used.add(fault.name)
        out.append(fault)
    return out
