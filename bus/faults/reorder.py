"""``reorder``: selected packets are held back so later ones overtake them (bus.link_faults)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from bus.faults.base import LinkFault, cli


class Reorder(LinkFault):
    """``percent`` of the selected packets are held back by ``gap_s`` so later ones overtake them."""

    effect: ClassVar[str] = "packets are held back so later ones overtake them"

    kind: Literal["reorder"] = "reorder"
    percent: float = Field(
        ge=0,
        le=100,
        description="share of the selected packets (%)",
        json_schema_extra=cli("--percent", "percent", "20"),
    )
    gap_s: float = Field(
        0.1,
        gt=0,
        le=60,
        description="how long a held-back packet waits (s)",
        json_schema_extra=cli("--gap", "seconds", "100ms"),
    )

    @classmethod
    def chaos_parameters(cls, rng: np.random.Generator) -> dict[str, Any]:
        return {"percent": round(float(rng.uniform(5, 30)), 1), "gap_s": round(float(rng.uniform(0.02, 0.2)), 3)}
