"""``jam-comms``: a radio jammer's zone."""

from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np

from bus.faults.base import Zone


class JamComms(Zone):
    """Vehicle-to-vehicle packets and ranging to and from vehicles inside the zone are lost."""

    effect: ClassVar[str] = "V2V packets and ranging to and from vehicles inside are lost"
    marker: ClassVar[tuple[float, float, float]] = (0.7, 0.3, 1.0)

    kind: Literal["jam-comms"] = "jam-comms"

    def jams_comms(self, xy_m: np.ndarray) -> bool:
        return self.inside(xy_m)
