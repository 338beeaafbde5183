"""``kill``: a vehicle process SIGKILLed, and started again later (by `swarm up`, the supervisor)."""

from __future__ import annotations

from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field

from bus.faults.base import ChaosSwarm, FaultBase, cli, vehicle_field


class Kill(FaultBase):
    """SIGKILL of a vehicle process at ``start_s``; restarted ``restart_after_s`` later (None: never).
    Added while a swarm runs by `swarm fault kill`, not `swarm fault add`."""

    applied_by: ClassVar[str] = "supervisor"
    effect: ClassVar[str] = "SIGKILL of the vehicle process, started again later"
    chaos_extra: ClassVar[bool] = False
    chaos_lasts: ClassVar[bool] = False  # its restart comes 3-15 s after it

    kind: Literal["kill"] = "kill"
    vehicle: int = vehicle_field()
    restart_after_s: float | None = Field(
        None,
        ge=0,
        le=1e7,
        description="start it again this much later (none: never)",
        json_schema_extra=cli("--restart-after", "seconds", "10s"),
    )

    def kill_us(self) -> int:
        """Sim time [us] of the kill (the supervisor and the world compare the same integers)."""
        return round(self.start_s * 1e6)

    def restart_us(self) -> int | None:
        return None if self.restart_after_s is None else round((self.start_s + self.restart_after_s) * 1e6)

    @classmethod
    def chaos(cls, rng: np.random.Generator, swarm: ChaosSwarm) -> dict[str, Any]:
        return {
            "vehicle": int(rng.integers(1, swarm.vehicles + 1)),
            "restart_after_s": round(float(rng.uniform(3, 15)), 1),
        }
