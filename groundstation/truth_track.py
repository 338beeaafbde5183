"""One vehicle's truth as the ground station keeps it: samples in stamp order, interpolated at the
stamps of the estimates it scores (groundstation.scoring), forgotten behind the watermark. Pure."""

from __future__ import annotations

import bisect
import math

import numpy as np

from bus.angles import wrap_angle as wrap


class TruthTrack:
    """One vehicle's truth samples, interpolated (angle-aware) at arbitrary stamps."""

    def __init__(self) -> None:
        self.stamps: list[int] = []
        self.poses: list[np.ndarray] = []

    def add(self, stamp_us: int, pose: np.ndarray) -> None:
        """One truth sample: pose (4,) [x m, y m, theta rad, height above the launch point m] at
        ``stamp_us``."""
        if self.stamps and stamp_us <= self.stamps[-1]:
            return  # duplicate or out of order: truth is published in order
        self.stamps.append(stamp_us)
        self.poses.append(pose)

    def covers(self, stamp_us: int) -> bool:
        return bool(self.stamps) and self.stamps[0] <= stamp_us <= self.stamps[-1]

    def in_gap(self, stamp_us: int) -> bool:
        """``stamp_us`` (covered) touches a truth sample of NaN: the data set has no truth there."""
        i = bisect.bisect_left(self.stamps, stamp_us)
        near = [self.poses[i]] if self.stamps[i] == stamp_us else [self.poses[i - 1], self.poses[i]]
        return any(math.isnan(p[0]) for p in near)

    def at(self, stamp_us: int) -> np.ndarray:
        i = bisect.bisect_left(self.stamps, stamp_us)
        if self.stamps[i] == stamp_us:
            return self.poses[i]
        t0, t1, p0, p1 = self.stamps[i - 1], self.stamps[i], self.poses[i - 1], self.poses[i]
        a = (stamp_us - t0) / (t1 - t0)
        pose = p0 + a * (p1 - p0)
        pose[2] = wrap(p0[2] + a * wrap(p1[2] - p0[2]))
        return pose

    def forget_before(self, stamp_us: int) -> None:
        keep = max(0, bisect.bisect_left(self.stamps, stamp_us) - 1)
        del self.stamps[:keep], self.poses[:keep]
