"""What visual odometry gives the filter (vehicle.visual_odometry): the motion between two camera
frames, as an input the filter holds like wheel odometry. A module of its own, without OpenCV, so
that a filter knows the message without loading the front end."""

from __future__ import annotations

from dataclasses import dataclass

ANNOUNCE_OFFSET_US = 1  # a visual motion's stamp: just after its first frame (vehicle.visual_odometry)


@dataclass(frozen=True)
class VisualMotion:
    """Mean forward speed (m/s) and yaw rate (rad/s) between two frames, with their variances from the
    fit (an infinite yaw-rate variance: not measured); stamped just after the first frame, ``seq``
    twice that frame's plus one (twice the first frame's: the unknown speed before it). Fed to the
    filter as its odometry (vehicle.visual_odometry)."""

    vehicle_id: int
    stamp_us: int
    seq: int
    speed_mps: float
    yaw_rate_radps: float
    speed_var: float
    yaw_rate_var: float
