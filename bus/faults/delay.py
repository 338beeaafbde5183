"""``delay``: selected packets arrive late (bus.link_faults applies it)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from bus.faults.base import LinkFault, cli


class Delay(LinkFault):
    """Every selected packet is late by ``delay_s`` +- ``jitter_s`` (uniform, normal with sigma
    jitter_s, or pareto: heavy tail, minimum delay_s - jitter_s, mean delay_s). Jitter reorders."""

    effect: ClassVar[str] = "packets arrive late; jitter reorders them"

    kind: Literal["delay"] = "delay"
    delay_s: float = Field(
        ge=0, le=60, description="how late (s)", json_schema_extra=cli("--delay", "seconds", "200ms")
    )
    jitter_s: float = Field(
        0.0, ge=0, le=60, description="spread of the delay (s)", json_schema_extra=cli("--jitter", "seconds", "50ms")
    )
    distribution: Literal["uniform", "normal", "pareto"] = Field(
        "uniform",
        description="of the delay: uniform, normal or pareto",
        json_schema_extra=cli("--distribution", "text", "normal"),
    )

    @classmethod
    def chaos_parameters(cls, rng: np.random.Generator) -> dict[str, Any]:
        return {
            "delay_s": round(float(rng.uniform(0.02, 0.3)), 3),
            "jitter_s": round(float(rng.uniform(0, 0.05)), 3),
            "distribution": str(rng.choice(["uniform", "normal", "pareto"])),
        }
