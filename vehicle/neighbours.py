"""What a vehicle hears from its neighbours: their MAVLink streams (V2V packets), kept raw and
decoded only when a ranging measurement needs the neighbour's estimate at its stamp."""

from __future__ import annotations

from collections import deque

import numpy as np

from bus.errors import DecodeError
from bus.mavlink_codec import MavlinkDecoder, StateEstimate

HISTORY = 250  # frames per neighbour (5 s of ODOMETRY at 50 Hz)


class Neighbours:
    def __init__(self, *, signing_key: bytes | None = None) -> None:
        self._frames: dict[int, deque[tuple[int, bytes]]] = {}
        self._decoder = MavlinkDecoder(signing_key=signing_key)
        self.rejected = 0

    def hear(self, vehicle_id: int, time_usec: int, frame: bytes) -> None:
        """File one V2V frame: an ODOMETRY stamped ``time_usec`` (checked by the caller)."""
        self._frames.setdefault(vehicle_id, deque(maxlen=HISTORY)).append((time_usec, frame))

    def estimate_at(self, vehicle_id: int, stamp_us: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Neighbour's position (2,) m and covariance (2, 2) m^2 at exactly ``stamp_us``, if heard."""
        for time_us, frame in reversed(self._frames.get(vehicle_id, ())):
            if time_us == stamp_us:
                try:
                    est = self._decoder.decode(frame)
                except DecodeError:
                    self.rejected += 1
                    return None
                if isinstance(est, StateEstimate) and est.vehicle_id == vehicle_id:
                    return est.position_m[:2].copy(), est.pose_covariance[:2, :2].copy()
                return None
            if time_us < stamp_us:
                return None
        return None
