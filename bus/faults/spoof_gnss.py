"""``spoof-gnss``: a GNSS spoofer's zone (sim.physical_faults keeps when each vehicle was captured)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from bus.faults.base import ChaosSwarm, Zone, cli, heading_field


class SpoofGnss(Zone):
    """Fixes inside the zone carry an offset growing at ``drift_mps`` along ``heading_deg`` (0 = +x)
    from the moment the vehicle is captured (enters the active zone)."""

    effect: ClassVar[str] = "fixes inside carry an offset growing from the moment a vehicle is captured"
    marker: ClassVar[tuple[float, float, float]] = (1.0, 0.6, 0.0)

    kind: Literal["spoof-gnss"] = "spoof-gnss"
    drift_mps: float = Field(
        0.5, gt=0, le=100, description="growth of the offset (m/s)", json_schema_extra=cli("--drift", "float", "0.5")
    )
    heading_deg: float = heading_field()

    @classmethod
    def chaos(cls, rng: np.random.Generator, swarm: ChaosSwarm) -> dict[str, Any]:
        return super().chaos(rng, swarm) | {
            "drift_mps": round(float(rng.uniform(0.2, 1.0)), 2),
            "heading_deg": round(float(rng.uniform(0, 360)), 1),
        }
