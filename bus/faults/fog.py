"""``fog``: a zone where the cameras see nothing (fog, smoke, a dazzling low sun). The example of the
recipe for a fault kind (docs/tutorial/adding-a-fault-kind.md): one module and one line in the
registry; the world asks each active fault what it silences, so nothing else changes."""

from __future__ import annotations

from typing import ClassVar, Literal

import numpy as np

from bus.faults.base import Zone
from bus.topics import Topic

BLINDED = (Topic.CAMERA, Topic.LANDMARK)  # what a camera gives: frames, or a replay's identified sightings


class Fog(Zone):
    """Camera frames and landmark sightings of vehicles inside the zone are lost."""

    effect: ClassVar[str] = "camera frames and landmark sightings inside the zone are lost"
    marker: ClassVar[tuple[float, float, float]] = (0.6, 0.7, 0.8)
    chaos_min_vehicles: ClassVar[int] = 10**9  # a chaos swarm flies without cameras: fog would change nothing

    kind: Literal["fog"] = "fog"

    def silences(self, vehicle_id: int, sensor: str, xy_m: np.ndarray) -> bool:
        return sensor in BLINDED and self.inside(xy_m)
