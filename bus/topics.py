"""The topics of the swarm's data: one name per kind of sample a vehicle receives, and the MAVLink
stream. A ``Topic`` is a ``StrEnum``: on the wire and in fault-plan globs it is its plain name
(``"gnss"``), in code it is typed, so a misspelt topic is an AttributeError, not a silent mismatch."""

from __future__ import annotations

from enum import StrEnum


class Topic(StrEnum):
    IMU = "imu"  # ImuSample
    ODOM = "odom"  # WheelOdometry
    GNSS = "gnss"  # GnssFix
    PRIOR = "prior"  # the launch prior (PosePrior)
    RANGING = "ranging"  # RangeBearing to a neighbour; fused as a CooperativeFix with its broadcast
    SEEN = "seen"  # SeenBy: a neighbour's sighting of this vehicle; fused as a SeenFix
    LANDMARK = "landmark"  # LandmarkSighting (a replayed data set's identified landmarks)
    CAMERA = "camera"  # CameraFrame
    MAVLINK = "mavlink"  # a vehicle's MAVLink stream (link faults only)


SENSOR_TOPICS = tuple(t for t in Topic if t is not Topic.MAVLINK)
