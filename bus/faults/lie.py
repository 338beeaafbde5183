"""``lie``: a vehicle that lies to its neighbours, applied by the liar's own outbound bus layer to the
V2V broadcasts it sends (its estimator and its MAVLink stream to the ground station stay honest, so
the ground station scores what the lie does to the others; docs/liars.md)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field, model_validator

from bus.faults.base import ChaosSwarm, FaultBase, cli, heading_field, vehicle_field


class Lie(FaultBase):
    """Vehicle ``vehicle`` broadcasts its estimate of ``stale_s`` before (a replay of its own past,
    stamped now; 0: its present one), moved by ``offset_m`` plus an offset growing at ``drift_mps``
    along ``heading_deg`` (0 = +x) since ``start_s``, with its covariance times ``cov_scale`` (0.01:
    a hundred times too sure). Validly signed: it speaks only for itself."""

    applied_by: ClassVar[str] = "outbound"
    effect: ClassVar[str] = "its V2V broadcasts lie (validly signed); see [a vehicle that lies](liars.md)"

    kind: Literal["lie"] = "lie"
    vehicle: int = vehicle_field()
    offset_m: tuple[float, float] = Field(
        (0.0, 0.0), description="constant offset [x, y] (m)", json_schema_extra=cli("--offset", "xy", "30,-30")
    )
    drift_mps: float = Field(
        0.0, ge=0, le=100, description="growth of the offset (m/s)", json_schema_extra=cli("--drift", "float", "0.5")
    )
    heading_deg: float = heading_field()
    cov_scale: float = Field(
        1.0,
        gt=0,
        le=1e6,
        description="broadcast covariance times this (0.01: 100x too sure)",
        json_schema_extra=cli("--cov-scale", "float", "0.01"),
    )
    stale_s: float = Field(
        0.0,
        ge=0,
        le=60,
        description="broadcast the estimate of this long before",
        json_schema_extra=cli("--stale", "seconds", "5s"),
    )

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

    @classmethod
    def chaos(cls, rng: np.random.Generator, swarm: ChaosSwarm) -> dict[str, Any]:
        return {
            "vehicle": int(rng.integers(1, swarm.vehicles + 1)),
            "offset_m": [round(float(c), 1) for c in rng.uniform(-30, 30, 2)],
            "drift_mps": round(float(rng.uniform(0, 0.3)), 2),
            "cov_scale": round(float(rng.choice([0.01, 0.1, 1.0])), 2),
        }
