"""The vehicle-to-vehicle side of a vehicle: neighbours' broadcast estimates, and ranging
measurements that wait ``latency_us`` for the neighbour's estimate of the same instant.

A ranging measurement stamped t becomes a CooperativeFix at the first cycle at or after
t + latency, once the neighbour's ODOMETRY for t has been heard (the world makes no ranging to or
from a comm-jammed vehicle); it reaches the estimator through the fusion horizon (which replays from t). The fixed wait
makes lockstep runs reproducible: what is fused at a cycle never depends on how fast the
neighbour's packet travelled.

Neighbours' frames are decoded and checked when they arrive: the sender must be the vehicle whose
key it came on, the covariance must be usable. Authenticity rests on the router: only vehicle j's
login may publish on ``v/j/v2v`` (bus.access); a vehicle holds no other vehicle's signing key.
"""

from __future__ import annotations

import heapq
import itertools
from collections import OrderedDict

import numpy as np

from bus import messages as m
from bus.errors import DecodeError
from bus.mavlink_codec import MavlinkDecoder, MavlinkRejected, NoEstimate, StateEstimate
from bus.rejections import Rejections
from vehicle.cooperative import CooperativeFix

HISTORY = 64        # broadcasts kept per neighbour (12 s at 5 Hz)
MAX_WAITING = 10_000


class V2V:
    def __init__(self, vehicle_id: int, *, latency_us: int, rejections: Rejections) -> None:
        self.vehicle_id, self.latency_us, self.rejections = vehicle_id, latency_us, rejections
        self._decoder = MavlinkDecoder()  # neighbours' keys are not ours to hold: no authentication here
        self._estimates: dict[int, OrderedDict[int, tuple[np.ndarray, np.ndarray]]] = {}
        self._waiting: list[tuple[int, int, m.RangeBearing]] = []
        self._order = itertools.count()
        self.sent = 0
        self.missing = 0

    def hear(self, sender: int, stamp_us: int, frame: bytes) -> None:
        """A neighbour's ODOMETRY frame (after link faults): decoded, checked and kept by stamp."""
        try:
            est = self._decoder.decode(frame)
        except MavlinkRejected as exc:
            self.rejections.reject(exc.reason, f"v2v from {sender}", str(exc))
            return
        except DecodeError as exc:
            self.rejections.reject("malformed", f"v2v from {sender}", str(exc))
            return
        if isinstance(est, NoEstimate) and est.vehicle_id == sender and est.time_usec == stamp_us:
            return  # the neighbour had no estimate at that epoch
        if not isinstance(est, StateEstimate) or est.vehicle_id != sender or est.time_usec != stamp_us:
            self.rejections.reject("impersonation", f"v2v from {sender}", "sender or stamp differs from the frame's")
            return
        history = self._estimates.setdefault(sender, OrderedDict())
        history[stamp_us] = (est.position_m[:2].copy(), est.pose_covariance[:2, :2].copy())
        while len(history) > HISTORY:
            history.popitem(last=False)

    def hold(self, measurement: m.RangeBearing) -> bool:
        """Keep a ranging measurement until its neighbour's broadcast is due; False when full."""
        if len(self._waiting) >= MAX_WAITING:
            self.rejections.reject("inbox_full", "ranging waiting for V2V", "too many waiting")
            return False
        heapq.heappush(self._waiting, (measurement.stamp_us, next(self._order), measurement))
        return True

    def awaited(self, now_us: int) -> list[tuple[int, int]]:
        """(neighbour, stamp) of every ranging measurement that matures by ``now_us``: whose
        broadcasts the cycle at ``now_us`` pairs them with."""
        return [(msg.target_id, stamp) for stamp, _, msg in self._waiting if stamp + self.latency_us <= now_us]

    def mature(self, now_us: int) -> list[CooperativeFix]:
        """Ranging measurements whose wait is over, paired with the neighbour's estimate."""
        out = []
        while self._waiting and self._waiting[0][0] + self.latency_us <= now_us:
            msg = heapq.heappop(self._waiting)[2]
            found = self._estimates.get(msg.target_id, {}).get(msg.stamp_us)
            if found is None:
                self.missing += 1
                continue
            out.append(CooperativeFix(msg.vehicle_id, msg.stamp_us, msg.seq, msg.target_id, msg.range_m,
                                      msg.bearing_rad, msg.covariance, *found))
        return out
