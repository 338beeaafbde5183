"""The fault plan: every fault the swarm can suffer, as validated models (pydantic), one module per
kind under bus/faults/ and one line each in ``KINDS``. What a kind declares (its parameters with their
flags, who applies it, its effect, its zone's colour, its chaos entry: bus.faults.base) is all there
is: `swarm fault add`, chaos timelines, the live view's zones and the docs' table are derived from
the registry (docs/tutorial/adding-a-fault-kind.md).

- physical faults, applied by the world: ``jam-gnss``, ``spoof-gnss``, ``jam-comms``, ``blackout``,
  ``fog``;
- link faults, applied by each receiving process's bus layer (``bus.link_faults``): ``delay``,
  ``loss``, ``duplicate``, ``reorder``, selected by source, destination and topic globs;
- ``kill``: the vehicle process is SIGKILLed at ``start_s`` and, with ``restart_after_s``, started
  again by the supervisor (``swarm up``);
- ``lie`` and ``accuse``: applied by the vehicle's own outbound bus layer to the V2V broadcasts it sends.

Endpoints are named ``v<id>`` (vehicles), ``gs`` (ground station) and ``world``.
"""

from __future__ import annotations

import fnmatch
import re
from typing import Annotated, Union

from pydantic import Field

from bus.faults.accuse import Accuse
from bus.faults.base import GLOB, LINK_TOPICS, NAME, ChaosSwarm, FaultBase, LinkFault, Zone
from bus.faults.blackout import Blackout
from bus.faults.delay import Delay
from bus.faults.duplicate import Duplicate
from bus.faults.fog import Fog
from bus.faults.jam_comms import JamComms
from bus.faults.jam_gnss import JamGnss
from bus.faults.kill import Kill
from bus.faults.lie import Lie
from bus.faults.loss import Loss
from bus.faults.reorder import Reorder
from bus.faults.spoof_gnss import SpoofGnss

# the registry: every kind once, in the order a chaos timeline draws them
KINDS: tuple[type[FaultBase], ...] = (
    Delay,
    Loss,
    Duplicate,
    Reorder,
    JamGnss,
    SpoofGnss,
    JamComms,
    Blackout,
    Kill,
    Lie,
    Accuse,
    Fog,
)
BY_KIND = {kind.kind_name(): kind for kind in KINDS}
Fault = Annotated[Union[KINDS], Field(discriminator="kind")]  # noqa: UP007 (a tuple of types, not an expression)
PHYSICAL_KINDS = tuple(k for k, kind in BY_KIND.items() if kind.applied_by == "world")
LINK_KINDS = tuple(k for k, kind in BY_KIND.items() if kind.applied_by == "link")
BEHAVIOUR_KINDS = tuple(k for k, kind in BY_KIND.items() if kind.applied_by == "outbound")

__all__ = [
    "GLOB",
    "LINK_TOPICS",
    "NAME",
    "Accuse",
    "Blackout",
    "ChaosSwarm",
    "Delay",
    "Duplicate",
    "Fog",
    "FaultBase",
    "JamComms",
    "JamGnss",
    "Kill",
    "Lie",
    "LinkFault",
    "Loss",
    "Reorder",
    "SpoofGnss",
    "Zone",
    "check_fault",
    "endpoints",
    "named",
]


def endpoints(vehicles: int) -> list[str]:
    """Every endpoint name of a swarm of ``vehicles``: world, gs, v1 .. vN."""
    return ["world", "gs", *(f"v{i}" for i in range(1, vehicles + 1))]


def check_fault(fault: FaultBase, vehicles: int) -> None:
    """Raise ValueError when ``fault`` names a vehicle or endpoint that is not in the swarm."""
    vehicle = getattr(fault, "vehicle", None)
    if vehicle is not None and vehicle > vehicles:
        raise ValueError(f"fault {fault.name or fault.kind}: vehicle {vehicle} does not exist ({vehicles} vehicles)")
    missing = [n for n in getattr(fault, "names", ()) if n > vehicles]
    if missing:
        raise ValueError(
            f"fault {fault.name or fault.kind}: --names v{missing[0]} does not exist ({vehicles} vehicles)"
        )
    if isinstance(fault, LinkFault):
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
