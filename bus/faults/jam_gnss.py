"""``jam-gnss``: a GNSS jammer's zone."""

from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np

from bus.faults.base import Zone
from bus.topics import Topic


class JamGnss(Zone):
    """No GNSS fix for vehicles inside the zone."""

    effect: ClassVar[str] = "no GNSS fix inside the zone"
    marker: ClassVar[tuple[float, float, float]] = (1.0, 0.2, 0.2)

    kind: Literal["jam-gnss"] = "jam-gnss"

    def silences(self, vehicle_id: int, sensor: str, xy_m: np.ndarray) -> bool:
        return sensor == Topic.GNSS and self.inside(xy_m)
