"""The vehicle-to-vehicle side of a vehicle: neighbours' broadcast estimates, comm jamming, and
ranging measurements that wait ``latency_us`` for the neighbour's estimate of the same instant.

A ranging measurement stamped t becomes a CooperativeFix at the first cycle at or after
t + latency, once the neighbour's ODOMETRY for t has been heard; it reaches the estimator through
the fusion horizon (which replays from t). The fixed wait makes lockstep runs reproducible: what is
fused at a cycle never depends on how fast the neighbour's packet travelled.
"""

from __future__ import annotations

import bisect
import heapq
import itertools
from collections import deque

from bus import messages as m
from vehicle.cooperative import CooperativeFix
from vehicle.neighbours import Neighbours

JAM_HISTORY = 500  # clock ticks remembered (10 s at 50 Hz)


class V2V:
    def __init__(self, vehicle_id: int, *, latency_us: int, signing_key: bytes | None = None) -> None:
        self.vehicle_id, self.latency_us = vehicle_id, latency_us
        self.neighbours = Neighbours(signing_key=signing_key)
        self._waiting: list[tuple[int, int, m.RangeBearing]] = []
        self._order = itertools.count()
        self._jam_stamps: deque[int] = deque(maxlen=JAM_HISTORY)
        self._jam_sets: deque[frozenset[int]] = deque(maxlen=JAM_HISTORY)
        self.missing = 0
        self.jammed = 0

    def on_tick(self, tick: m.ClockTick) -> None:
        if not self._jam_stamps or tick.stamp_us > self._jam_stamps[-1]:
            self._jam_stamps.append(tick.stamp_us)
            self._jam_sets.append(frozenset(tick.comm_jammed))

    def jammed_at(self, stamp_us: int) -> frozenset[int]:
        """Vehicles in a comm-jamming zone at the tick that covers ``stamp_us``."""
        i = bisect.bisect_left(self._jam_stamps, stamp_us)
        return self._jam_sets[i] if i < len(self._jam_sets) else (self._jam_sets[-1] if self._jam_sets else frozenset())

    def hear(self, sender: int, stamp_us: int, frame: bytes) -> None:
        """A neighbour's MAVLink frame (after link faults); lost if either end is comm-jammed."""
        jammed = self.jammed_at(stamp_us)
        if sender in jammed or self.vehicle_id in jammed:
            self.jammed += 1
            return
        self.neighbours.hear(sender, stamp_us, frame)

    def hold(self, measurement: m.RangeBearing) -> None:
        heapq.heappush(self._waiting, (measurement.stamp_us, next(self._order), measurement))

    def mature(self, now_us: int) -> list[CooperativeFix]:
        """Ranging measurements whose wait is over, paired with the neighbour's estimate."""
        out = []
        while self._waiting and self._waiting[0][0] + self.latency_us <= now_us:
            msg = heapq.heappop(self._waiting)[2]
            found = self.neighbours.estimate_at(msg.target_id, msg.stamp_us)
            if found is None:
                self.missing += 1
                continue
            out.append(CooperativeFix(msg.vehicle_id, msg.stamp_us, msg.seq, msg.target_id, msg.range_m,
                                      msg.bearing_rad, msg.covariance, *found))
        return out
