"""The fault plan's physical faults (applied by the world), as validated config models.

Times are sim seconds. A fault is active for ``start_s <= t < start_s + for_s`` (``for_s`` None:
until the end of the run). Zones are circles in the world's x-y plane (metres).
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field


class _Fault(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    name: str = Field("", max_length=64, description="unique label; assigned when empty")
    start_s: float = Field(0.0, ge=0)
    for_s: float | None = Field(None, gt=0)

    def active(self, t_s: float) -> bool:
        return self.start_s <= t_s and (self.for_s is None or t_s < self.start_s + self.for_s)


class _Zone(_Fault):
    center_m: tuple[float, float]
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
    heading_deg: float = 0.0


class Blackout(_Fault):
    """One sensor of one vehicle stays silent."""

    kind: Literal["blackout"] = "blackout"
    vehicle: int = Field(ge=1, le=250)
    sensor: Literal["imu", "odom", "gnss"]


PhysicalFault = Annotated[Union[JamGnss, SpoofGnss, Blackout], Field(discriminator="kind")]


def named(faults: list) -> list:
    """The faults with empty names replaced by ``<kind>-<n>`` (n counts per kind, from 1)."""
    counts: dict[str, int] = {}
    out = []
    for fault in faults:
        counts[fault.kind] = counts.get(fault.kind, 0) + 1
        out.append(fault if fault.name else fault.model_copy(update={"name": f"{fault.kind}-{counts[fault.kind]}"}))
    return out
