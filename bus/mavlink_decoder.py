"""Reading MAVLink 2: frames cut from a byte string (``split_frames``), a frame's header without
decoding it (``frame_header``), and ``MavlinkDecoder``, which authenticates each frame and decodes it
to a ``bus.odometry_content`` estimate (ODOMETRY, read from the wire by ``bus.odometry_wire``) or a
``bus.mavlink_messages`` message. Signing is checked here rather than by pymavlink (the module
docstring of ``bus.mavlink_codec`` says why)."""

from __future__ import annotations

import hashlib
import hmac
import math
from collections import Counter
from collections.abc import Callable

from pymavlink.dialects.v20 import common as mavlink2

from bus.errors import DecodeError, MavlinkRejected
from bus.estimate import PoseEstimate
from bus.mavlink_messages import (
    DISTRUST,
    Accusation,
    EstimatorStatus,
    Heartbeat,
    StatusText,
    SystemTime,
    signing_now,
)
from bus.odometry_content import NoEstimate, StateEstimate, estimate_of, planar_estimate_of, pose_of
from bus.odometry_wire import odometry_fields

NEW_STREAM_TOLERANCE = 6_000_000  # 60 s in 10-us units, as in the MAVLink signing spec
FUTURE_TOLERANCE = 6_000_000  # 60 s in 10-us units


def split_frames(buffer: bytes) -> tuple[list[bytes], int]:
    """Cut a byte string of concatenated MAVLink 2 frames into frames (by their length fields).
    Returns the frames and the number of trailing bytes that do not form a frame (total)."""
    frames, i, n = [], 0, len(buffer)
    while i + 12 <= n and buffer[i] == mavlink2.PROTOCOL_MARKER_V2:
        length = 12 + buffer[i + 1] + (13 if buffer[i + 2] & mavlink2.MAVLINK_IFLAG_SIGNED else 0)
        if i + length > n:
            break
        frames.append(bytes(buffer[i : i + length]))
        i += length
    return frames, n - i


class MavlinkDecoder:
    """Decodes single MAVLink 2 frames and authenticates them; counts every rejection by reason.

    ``key_for(sysid)`` gives each sender's signing key (None: not a known sender, rejected as
    unknown_sysid); ``signing_key`` is the same key for every sender. Without either, frames are
    not authenticated (insecure runs, or neighbours that cannot hold each other's keys)."""

    def __init__(
        self,
        *,
        signing_key: bytes | None = None,
        require_signing: bool | None = None,
        key_for: Callable[[int], bytes | None] | None = None,
    ) -> None:
        self._key_for = (
            key_for if key_for is not None else (None if signing_key is None else (lambda sysid: signing_key))
        )
        self._require = self._key_for is not None if require_signing is None else require_signing
        self._mav = mavlink2.MAVLink(None)
        self._stream_timestamps: dict[tuple[int, int, int], int] = {}
        self.rejected: Counter[str] = Counter()

    def decode(
        self, frame: bytes
    ) -> StateEstimate | NoEstimate | Heartbeat | EstimatorStatus | StatusText | SystemTime | Accusation | None:
        """One frame -> StateEstimate (NoEstimate for an ODOMETRY of unknown covariance), Heartbeat,
        EstimatorStatus, StatusText, SystemTime, Accusation (a NAMED_VALUE_INT named "distrust"), or
        None for other types.

        Raises DecodeError for malformed frames, MavlinkRejected for failed authentication.
        """
        fields = odometry_fields(frame)
        if fields is not None:  # the common frame, read without pymavlink's message object (bus.odometry_wire)
            return self._accepted(frame, frame[5], frame[6], fields)
        try:
            msg = self._mav.decode(bytearray(frame))
        except Exception as exc:  # pymavlink raises MAVError, struct.error, IndexError, ...
            raise DecodeError(f"malformed MAVLink frame: {exc}") from None
        if len(msg.get_msgbuf()) != len(frame) or frame[0] != mavlink2.PROTOCOL_MARKER_V2:
            raise DecodeError("payload is not exactly one MAVLink 2 frame")
        odometry = _wire_fields(msg) if isinstance(msg, mavlink2.MAVLink_odometry_message) else None
        estimate = self._accepted(frame, msg.get_srcSystem(), msg.get_srcComponent(), odometry)
        if estimate is not None:
            return estimate
        if isinstance(msg, mavlink2.MAVLink_heartbeat_message):
            return Heartbeat(msg.get_srcSystem(), msg.type, msg.system_status)
        if isinstance(msg, mavlink2.MAVLink_estimator_status_message):
            if not (math.isfinite(msg.pos_horiz_ratio) and math.isfinite(msg.pos_horiz_accuracy)):
                raise DecodeError(f"ESTIMATOR_STATUS from sysid {msg.get_srcSystem()} has non-finite fields")
            return EstimatorStatus(
                msg.get_srcSystem(), msg.time_usec, msg.flags, msg.pos_horiz_ratio, msg.pos_horiz_accuracy
            )
        if isinstance(msg, mavlink2.MAVLink_statustext_message):
            return StatusText(msg.get_srcSystem(), msg.severity, _text(msg.text))
        if isinstance(msg, mavlink2.MAVLink_system_time_message):
            return SystemTime(msg.get_srcSystem(), msg.time_boot_ms)
        if isinstance(msg, mavlink2.MAVLink_named_value_int_message) and _text(msg.name) == DISTRUST:
            return Accusation(msg.get_srcSystem(), msg.time_boot_ms, msg.value)
        return None

    def decode_pose(
        self, frame: bytes
    ) -> PoseEstimate | NoEstimate | Heartbeat | EstimatorStatus | StatusText | SystemTime | Accusation | None:
        """``decode``, with an ODOMETRY's estimate as the planar estimate ``pose_of`` makes of it (the
        same checks and refusals; a neighbour's broadcast is read so)."""
        fields = odometry_fields(frame)
        if fields is not None:
            return self._accepted(frame, frame[5], frame[6], fields, planar_estimate_of)
        decoded = self.decode(frame)
        return pose_of(decoded) if isinstance(decoded, StateEstimate) else decoded

    def _accepted(self, frame: bytes, sysid: int, compid: int, odometry: tuple | None, read=estimate_of):
        """Authenticate ``frame``, then the estimate its ODOMETRY fields (wire order; None: not an
        ODOMETRY) carry, as ``read`` (estimate_of or planar_estimate_of) gives it; a refusal is counted
        by reason and raised (MavlinkRejected)."""
        try:
            self._authenticate(bytes(frame), sysid, compid)
            return None if odometry is None else read(sysid, odometry)
        except MavlinkRejected as exc:
            self.rejected[exc.reason] += 1
            raise

    def _authenticate(self, frame: bytes, sysid: int, compid: int) -> None:
        signed = bool(frame[2] & mavlink2.MAVLINK_IFLAG_SIGNED)
        if self._key_for is None:
            return
        key = self._key_for(sysid)
        if key is None:
            raise MavlinkRejected("unknown_sysid", f"sysid {sysid} is not a vehicle of this swarm")
        if not signed:
            if self._require:
                raise MavlinkRejected("unsigned", f"sysid {sysid} sent an unsigned frame")
            return
        expected = hashlib.sha256(key + frame[:-6]).digest()[:6]
        if not hmac.compare_digest(expected, frame[-6:]):
            raise MavlinkRejected("bad_signature", f"sysid {sysid}: signature does not match its key")
        stream = (frame[-13], sysid, compid)
        stamp = int.from_bytes(frame[-12:-6], "little")
        last = self._stream_timestamps.get(stream)
        now = signing_now()
        if stamp > now + FUTURE_TOLERANCE:
            raise MavlinkRejected("future_timestamp", f"sysid {sysid}: signing timestamp more than 60 s ahead")
        if last is not None and stamp <= last:
            raise MavlinkRejected("replay", f"sysid {sysid}: timestamp {stamp} not after {last}")
        if last is None and stamp + NEW_STREAM_TOLERANCE < now:
            raise MavlinkRejected("stale_stream", f"sysid {sysid}: new stream more than 60 s old")
        if len(self._stream_timestamps) >= 4096 and stream not in self._stream_timestamps:
            self._stream_timestamps.clear()  # bounded: 256 links x known senders; a flood of links starts over
        self._stream_timestamps[stream] = stamp


def _wire_fields(msg: mavlink2.MAVLink_odometry_message) -> tuple:
    """A decoded ODOMETRY's fields in wire order (bus.odometry_wire)."""
    fields = (msg.time_usec, msg.x, msg.y, msg.z, *msg.q, msg.vx, msg.vy, msg.vz)
    fields += (msg.rollspeed, msg.pitchspeed, msg.yawspeed, *msg.pose_covariance, *msg.velocity_covariance)
    return fields + (msg.frame_id, msg.child_frame_id, msg.reset_counter, msg.estimator_type, msg.quality)


def _text(field: str | bytes) -> str:
    """A MAVLink char array as text, without its NUL padding."""
    raw = field if isinstance(field, str) else bytes(field).decode("utf-8", "replace")
    return raw.rstrip("\x00")


def frame_header(frame: bytes) -> tuple[int, int, int, int | None] | None:
    """(sysid, seq, msgid, time_usec or None) read from a raw MAVLink 2 frame without decoding it,
    or None if it is not one. ``time_usec`` is the first field of ODOMETRY and ESTIMATOR_STATUS."""
    if len(frame) < 12 or frame[0] != mavlink2.PROTOCOL_MARKER_V2:
        return None
    msgid = int.from_bytes(frame[7:10], "little")
    stamp = None
    if msgid in (mavlink2.MAVLINK_MSG_ID_ODOMETRY, mavlink2.MAVLINK_MSG_ID_ESTIMATOR_STATUS):
        payload = bytes(frame[10 : 10 + min(frame[1], 8)])
        stamp = int.from_bytes(payload.ljust(8, b"\0"), "little")  # MAVLink 2 trims trailing zeros
    return frame[5], frame[4], msgid, stamp
