"""``loss``: selected packets are lost (bus.link_faults applies it)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from bus.faults.base import LinkFault, cli


class Loss(LinkFault):
    """``percent`` of the selected packets are lost: independently, or with ``burst`` (mean burst
    length in packets) in Gilbert-Elliott bursts with the same long-run loss rate."""

    effect: ClassVar[str] = "packets are lost, independently or in bursts"

    kind: Literal["loss"] = "loss"
    percent: float = Field(
        ge=0,
        le=100,
        description="share of the selected packets (%)",
        json_schema_extra=cli("--percent", "percent", "30"),
    )
    burst: float | None = Field(
        None,
        ge=1,
        le=1e6,
        description="mean burst length in packets (Gilbert-Elliott)",
        json_schema_extra=cli("--burst", "float", "5"),
    )

    @classmethod
    def chaos_parameters(cls, rng: np.random.Generator) -> dict[str, Any]:
        fault: dict[str, Any] = {"percent": round(float(rng.uniform(5, 40)), 1)}
        if rng.random() < 0.5:
            fault["burst"] = round(float(rng.uniform(2, 8)), 1)
        return fault
