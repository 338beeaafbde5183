"""``duplicate``: selected packets arrive twice (bus.link_faults applies it)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from bus.faults.base import LinkFault, cli


class Duplicate(LinkFault):
    """``percent`` of the selected packets arrive twice."""

    effect: ClassVar[str] = "packets arrive twice"

    kind: Literal["duplicate"] = "duplicate"
    percent: float = Field(
        ge=0,
        le=100,
        description="share of the selected packets (%)",
        json_schema_extra=cli("--percent", "percent", "10"),
    )

    @classmethod
    def chaos_parameters(cls, rng: np.random.Generator) -> dict[str, Any]:
        return {"percent": round(float(rng.uniform(5, 30)), 1)}
