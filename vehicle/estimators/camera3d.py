"""The 3-D camera's part for the planar filters (bus.sensors.camera3d): none of them can use a UAV's
tracked points (their state is [x, y, heading]; the points' depth and the map are 3-D), so the part
registers no handler and the points are ignored. ``ar-ekf-slam-3d`` (vehicle.estimators.ar_ekf_slam_3d)
is the estimator that fuses them."""

from __future__ import annotations

from bus.config import SensorSpec
from vehicle.estimators.parts import BooklessPart, Handler


class Camera3dUnused(BooklessPart):
    """A planar filter's part for the 3-D camera: nothing (module docstring)."""

    def __init__(self, spec: SensorSpec) -> None: ...

    def handlers(self) -> dict[type, Handler]:
        return {}
