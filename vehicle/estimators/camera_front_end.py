"""The camera front end of the vision SLAM map (vehicle.estimators.vision_map): a frame judged (garbage
is counted and reported once, never fused), then its keypoints (SIFT or ORB) as range and bearing with
the ground scale the frame carries, and their covariances from the keypoints' pixel noise
(vehicle.vision.features). What it found is remembered for the few frames a fusion-horizon replay may
meet again: a pure function of the pixels, detected once."""

from __future__ import annotations

import cv2
import numpy as np

from bus import messages as m
from vehicle.estimators.parts import Reject
from vehicle.vision import features

FRAMES_REMEMBERED = 32  # front-end results kept for replays (3.2 s at 10 Hz; the horizon is 0.5 s)
Found = tuple[features.Features, np.ndarray, np.ndarray]  # keypoints, [range, bearing] (k, 2), covariances (k, 2, 2)


class CameraFrontEnd:
    """Vehicle ``vehicle_id``'s front end with ``detector`` ("sift" or "orb"); ``reject(reason, where,
    detail)`` counts garbage frames; ``results``: where it remembers each frame's keypoints by (stamp,
    seq): estimators fed the same frames (a Monte Carlo comparison) may share one and detect once."""

    def __init__(
        self,
        *,
        vehicle_id: int,
        keypoint_sigma_px: float,
        detector: str = "sift",
        reject: Reject | None = None,
        results: dict | None = None,
    ) -> None:
        cv2.setNumThreads(1)  # one core per vehicle process: OpenCV's thread pool would fight the others for it
        self.vehicle_id, self.keypoint_sigma_px = vehicle_id, keypoint_sigma_px
        self._detector = features.make_detector(detector)
        self.norm = cv2.NORM_L2 if detector == "sift" else cv2.NORM_HAMMING  # how descriptors compare
        self._reject = reject or (lambda reason, where, detail: None)
        self._judged_until_us = -1  # garbage frames are reported once, replays or not
        self._seen: dict[tuple[int, int], Found] = {} if results is None else results

    def usable(self, frame: m.CameraFrame) -> bool:
        """False for a garbage frame (reported the first time it is met)."""
        reason = features.garbage_reason(frame.pixels)
        if reason is None:
            return True
        if frame.stamp_us > self._judged_until_us:  # a replay meets the same frame again
            self._judged_until_us = frame.stamp_us
            self._reject("garbage_frame", f"camera of vehicle {self.vehicle_id}", reason)
        return False

    def observe(self, frame: m.CameraFrame) -> Found:
        """Keypoints, [range, bearing] (k, 2) and their covariances (k, 2, 2) of a usable frame."""
        key = (frame.stamp_us, frame.seq)
        if key not in self._seen:
            found = features.detect(np.ascontiguousarray(frame.pixels), self._detector)
            size, scale = frame.pixels.shape[0], frame.metres_per_pixel
            z = features.range_bearing(found.points_px, size, scale)
            R = features.pixel_noise_to_range_bearing(found.points_px, size, scale, self.keypoint_sigma_px)
            self._seen[key] = (found, z, R)
            while len(self._seen) > FRAMES_REMEMBERED:
                self._seen.pop(next(iter(self._seen)))
        return self._seen[key]

    def remembered(self, stamp_us: int, seq: int) -> Found | None:
        """What it found in a recent frame, if still remembered (experiments)."""
        return self._seen.get((stamp_us, seq))
