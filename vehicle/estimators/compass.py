"""The filter part that fuses a compass's heading (bus.sensors.compass): one gated one-dimensional
update of the heading state, the innovation wrapped to +-pi, with the variance the fix reports. Any
estimator of a vehicle whose datasheet has the compass on gets it (vehicle.estimators.get_estimator)."""

from __future__ import annotations

import numpy as np

from bus.angles import wrap_angle
from bus.config import SensorSpec
from bus.sensors.compass import CompassHeading
from bus.statistics import gate_threshold
from vehicle.estimators.parts import BooklessPart, Fusing, Handler

HEADING = 2  # the heading's index in every vehicle state [x, y, theta, ...]
GATE_PROBABILITY = 0.9995  # as the GNSS gate's default


class CompassPart(BooklessPart):  # the compass keeps no book in the state
    """Compass headings into the heading state (module docstring)."""

    def __init__(self, spec: SensorSpec) -> None:
        self._gate = gate_threshold(1, GATE_PROBABILITY)
        self.fused = self.rejected = 0  # totals of this process (not restored by replays)

    def handlers(self) -> dict[type, Handler]:
        return {CompassHeading: self.on_heading}

    def on_heading(self, fusing: Fusing, msg: CompassHeading) -> None:
        fusing.propagate_to(msg.stamp_us)
        s = fusing.state
        y = np.array([wrap_angle(msg.heading_rad - float(s.x[HEADING]))])
        H = np.ones((1, 1))
        result = fusing.store.update(s, y, H, np.array([[msg.variance_rad2]]), self._gate, [HEADING])
        if result.accepted:
            self.fused += 1
        else:
            self.rejected += 1
