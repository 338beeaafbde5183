"""The vehicle's visual odometry front end (``vehicle.odometry = "visual"``): each camera frame against
the one before (vehicle.vision.odometry) gives the speed and yaw rate over the interval between them,
with variances from the fit. It stands in for wheel odometry on a vehicle without wheels.

The motion over [t1, t2] is known only when the frame of t2 arrives: the node announces, with the
frame of t1, a measurement stamped t1 + 1 us (the fusion horizon keeps a checkpoint there, after the
frame's own update) and pushes it at t2, so the filter holds the mean speed over the interval it
belongs to instead of one frame late; a replay redoes only the predictions since t1.
"""

from __future__ import annotations

import numpy as np

from bus import messages as m
from bus.rejections import Reject
from vehicle.vision import features
from vehicle.vision.motion import ANNOUNCE_OFFSET_US, VisualMotion
from vehicle.vision.odometry import NoMotion, VoSpec, frame_motion


class VisualOdometry:
    def __init__(self, vehicle_id: int, *, detector: str = "sift", reject: Reject, spec: VoSpec = VoSpec()) -> None:
        self.vehicle_id, self.spec, self._reject = vehicle_id, spec, reject
        self._detector = features.make_detector(detector)
        self._last: tuple[m.CameraFrame, features.Features] | None = None
        self._known: tuple[int, float, float] | None = None  # (stamp us, speed, its variance) of the last motion
        self.failures = 0

    def on_frame(self, frame: m.CameraFrame) -> list[VisualMotion]:
        """What this frame tells of the speed: at the first frame, that it is unknown (the spec's
        ``unknown_speed_mps`` as its sigma); later, the motion since the previous frame, or when
        none is found (counted), the last speed with its sigma grown by ``unseen_accel_mps2`` over
        the time since it was measured. The yaw rate is left to the gyro (infinite variance) but when
        measured. Stamps and seqs: VisualMotion's."""
        if features.garbage_reason(frame.pixels) is not None:
            return []  # the SLAM front end reports garbage frames; the next good frame goes on from the last
        found = features.detect(np.ascontiguousarray(frame.pixels), self._detector)
        last, self._last = self._last, (frame, found)
        if last is None:
            unknown = self.spec.unknown_speed_mps**2
            self._known = (frame.stamp_us, 0.0, unknown)
            return [VisualMotion(self.vehicle_id, frame.stamp_us, 2 * frame.seq, 0.0, 0.0, unknown, np.inf)]
        previous, before = last
        if frame.stamp_us <= previous.stamp_us:
            return []
        dt = (frame.stamp_us - previous.stamp_us) * 1e-6
        stamp, seq = previous.stamp_us + ANNOUNCE_OFFSET_US, 2 * previous.seq + 1
        rng = np.random.default_rng([self.vehicle_id, frame.stamp_us])
        motion = frame_motion(before, found, frame.pixels.shape[0], frame.metres_per_pixel, rng, self.spec)
        if isinstance(motion, NoMotion) or abs(previous.metres_per_pixel - frame.metres_per_pixel) > 1e-9:
            self.failures += 1
            detail = motion.reason if isinstance(motion, NoMotion) else "the ground scale changed"
            self._reject("no_visual_motion", f"visual odometry of vehicle {self.vehicle_id}", detail)
            known_us, speed, variance = self._known
            grown = variance + (self.spec.unseen_accel_mps2 * (frame.stamp_us - known_us) * 1e-6) ** 2
            return [VisualMotion(self.vehicle_id, stamp, seq, speed, 0.0, grown, np.inf)]
        speed, variance = float(motion.delta[0]) / dt, float(motion.covariance[0, 0]) / dt**2
        self._known = (frame.stamp_us, speed, variance)
        rate, rate_variance = float(motion.delta[2]) / dt, float(motion.covariance[2, 2]) / dt**2
        return [VisualMotion(self.vehicle_id, stamp, seq, speed, rate, variance, rate_variance)]
