"""``accuse``: a vehicle whose V2V broadcasts accuse the named vehicles, validly signed, whatever its
own evidence (an insider turning the swarm against honest vehicles; docs/security.md), applied by its
own outbound bus layer."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

import numpy as np
from pydantic import Field, model_validator

from bus.faults.base import ChaosSwarm, FaultBase, cli, vehicle_field


class Accuse(FaultBase):
    """Vehicle ``vehicle`` accuses ``names`` in every V2V broadcast (after whom its own monitor
    distrusts, at most 8 in all: bus.mavlink_codec.MAX_ACCUSED), validly signed."""

    applied_by: ClassVar[str] = "outbound"
    effect: ClassVar[str] = (
        "its V2V broadcasts accuse the named vehicles (validly signed); see "
        "[security](security.md#insiders-the-threat-model)"
    )
    chaos_min_vehicles: ClassVar[int] = 2  # one vehicle has nobody to accuse

    kind: Literal["accuse"] = "accuse"
    vehicle: int = vehicle_field()
    names: tuple[Annotated[int, Field(ge=1, le=250)], ...] = Field(
        min_length=1,
        max_length=8,
        description="the vehicles it accuses",
        json_schema_extra=cli("--names", "vehicles", "v1,v2"),
    )

    @model_validator(mode="after")
    def _accuses_others(self) -> Accuse:
        if self.vehicle in self.names:
            raise ValueError(f"--names: v{self.vehicle} would accuse itself")
        return self

    @classmethod
    def chaos(cls, rng: np.random.Generator, swarm: ChaosSwarm) -> dict[str, Any]:
        vehicle = int(rng.integers(1, swarm.vehicles + 1))
        others = [v for v in range(1, swarm.vehicles + 1) if v != vehicle]
        names = rng.choice(others, size=min(len(others), int(rng.integers(1, 4))), replace=False)
        return {"vehicle": vehicle, "names": sorted(int(n) for n in names)}
