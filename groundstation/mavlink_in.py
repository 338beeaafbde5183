"""The ground station's MAVLink intake: every vehicle's byte stream, cut into frames, passed through
this process's link faults, authenticated with the sender's own key, and checked (the sysid must be
the vehicle whose key it came on, the estimate must be usable and stamped near the swarm's time).
Anything else is counted by reason and dropped; nothing here raises.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable
from typing import Any

from bus.errors import DecodeError
from bus.link_faults import Arrival, LinkFaultStage
from bus.mavlink_codec import MavlinkDecoder, MavlinkRejected, StateEstimate, frame_header, split_frames
from bus.rejections import Rejections
from bus.secrets import vehicle_signing_key
from bus.topics import Topic
from groundstation.link_quality import StreamQuality

MAX_STREAM_BYTES = 64 << 10  # one tick of one vehicle's frames
FUTURE_US = 10_000_000  # estimates may be this far ahead of the ground station's clock
PAST_US = 120_000_000  # and this far behind it


class MavlinkIntake:
    def __init__(
        self, *, vehicles: int, master_key: bytes | None, fault_seed: int, faults: tuple, rejections: Rejections
    ) -> None:
        self.vehicles, self.rejections = vehicles, rejections
        keys = {vid: vehicle_signing_key(master_key, vid) for vid in range(1, vehicles + 1)} if master_key else None
        self.decoder = MavlinkDecoder(key_for=keys.get) if keys is not None else MavlinkDecoder()
        self.links = LinkFaultStage("gs", seed=fault_seed, faults=faults)
        self.quality: dict[int, StreamQuality] = {}
        self.stream_stamp_us: dict[int, int] = {}
        self.rejected_by_vehicle: Counter[int] = Counter()  # keyed by the vehicle whose key it came on

    def _reject(self, vehicle_id: int, reason: str, where: str, detail: str) -> None:
        self.rejected_by_vehicle[vehicle_id] += 1
        self.rejections.reject(reason, where, detail)

    def offer(self, key: str, vehicle_id: int, payload: bytes) -> list[tuple[int, bytes]]:
        """One message from ``v/<vehicle_id>/mavlink``: its frames that pass the link faults now, as
        (vehicle id, frame). Frames without a time (HEARTBEAT, STATUSTEXT) take their stream's last
        stamp, so what the faults do never depends on when a frame happened to arrive."""
        if vehicle_id > self.vehicles:
            self.rejections.reject("unknown_vehicle", key, f"the swarm has {self.vehicles} vehicles")
            return []
        frames, rest = split_frames(payload)
        if rest or not frames:
            self._reject(vehicle_id, "malformed", key, f"{rest} bytes are not MAVLink 2 frames")
        out = []
        for frame in frames:
            header = frame_header(frame)
            if header[3] is not None:
                self.stream_stamp_us[vehicle_id] = max(header[3], self.stream_stamp_us.get(vehicle_id, -1))
            stamp = self.stream_stamp_us.get(vehicle_id, 0)
            out += self.links.offer(Arrival(key, f"v{vehicle_id}", Topic.MAVLINK, stamp, (vehicle_id, frame)))
        return out

    def decode(self, vehicle_id: int, frame: bytes, now_us: int) -> Any:
        """Authenticate and check one frame; the decoded message, or None (counted) when rejected."""
        header = frame_header(frame)
        self.quality.setdefault(vehicle_id, StreamQuality()).see(header[1])  # as a GCS counts its link
        where = f"MAVLink of vehicle {vehicle_id}"
        try:
            decoded = self.decoder.decode(frame)
        except MavlinkRejected as exc:
            self._reject(vehicle_id, exc.reason, where, str(exc))
            return None
        except DecodeError as exc:
            self._reject(vehicle_id, "malformed", where, str(exc))
            return None
        sysid = getattr(decoded, "vehicle_id", header[0])
        if sysid != vehicle_id:
            self._reject(vehicle_id, "impersonation", where, f"frame from sysid {sysid} on vehicle {vehicle_id}'s key")
            return None
        if isinstance(decoded, StateEstimate) and not now_us - PAST_US <= decoded.time_usec <= now_us + FUTURE_US:
            self._reject(vehicle_id, "stamp_out_of_range", where, f"time_usec {decoded.time_usec}, sim time {now_us}")
            return None
        return decoded

    def release(self, now_us: int, ready: Callable[[Arrival, int], bool] | None = None) -> list[tuple[int, bytes]]:
        return self.links.release(now_us, ready)


def said_at(time_boot_ms: int, now_us: int) -> int | None:
    """The sim time (us) a SYSTEM_TIME's ``time_boot_ms`` (modulo 2^32 ms) names, taken as the one
    nearest the ground station's ``now_us``; None when that is not near it (``PAST_US`` behind to
    ``FUTURE_US`` ahead, as for estimates)."""
    wrap_ms, now_ms = 2**32, now_us // 1000
    ms = now_ms - (now_ms - time_boot_ms) % wrap_ms  # the latest at or before now
    if now_ms - ms > wrap_ms // 2:
        ms += wrap_ms
    stamp_us = ms * 1000
    return stamp_us if now_us - PAST_US <= stamp_us <= now_us + FUTURE_US else None
