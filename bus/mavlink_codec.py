"""MAVLink 2 codec for vehicle state: ODOMETRY (#331), HEARTBEAT (#0), ESTIMATOR_STATUS (#230),
STATUSTEXT (#253) and a vehicle's accusations (NAMED_VALUE_INT #252 named "distrust", the value a
neighbour's id: what the vehicle's neighbour monitor distrusts, sent after its V2V ODOMETRY), with
message signing.

Where a planar ``bus.estimate.PoseEstimate`` sits in an ODOMETRY, and what an ODOMETRY must say to
be accepted, is ``bus.odometry_content``'s (``odometry_of`` / ``pose_of``, re-exported here); a
vehicle packs its estimate (``MavlinkEncoder.pose_odometry``) and reads its neighbours' broadcasts
(``MavlinkDecoder.decode_pose``) straight between the planar estimate and the wire. ``Health``
becomes ESTIMATOR_STATUS (``status_of``).

Signing (MAVLink 2, 32-byte key, one per vehicle): outgoing frames carry a 48-bit timestamp in units
of 10 us since 2015-01-01 and a truncated SHA-256 signature. Incoming frames are verified here rather
than by pymavlink, because pymavlink 2.4.50 stores a stream's timestamp *before* checking the
signature: one forged frame with a far-future timestamp would make every genuine frame look like a
replay. We check the signature first, refuse timestamps more than 60 s ahead of our clock (so even a
key holder cannot freeze a stream), and only then advance the stream's timestamp.

Contents are checked too (``bus.odometry_content``): an ODOMETRY whose [x, y, yaw] covariance is not
symmetric positive definite, or is absurdly large, or whose values are not finite, is rejected as
degenerate.
"""

from __future__ import annotations

import hashlib
import hmac
import math
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from bus.errors import DecodeError
from bus.errors import MavlinkRejected as MavlinkRejected
from bus.estimate import Health, PoseEstimate
from bus.odometry_content import _BODY_FRD, _LOCAL_NED, _UPPER, estimate_of, planar_estimate_of, planar_fields
from bus.odometry_content import MAX_POSITION_M as MAX_POSITION_M
from bus.odometry_content import MAX_VARIANCE as MAX_VARIANCE
from bus.odometry_content import NOT_ESTIMATED_VAR as NOT_ESTIMATED_VAR
from bus.odometry_content import NoEstimate as NoEstimate
from bus.odometry_content import StateEstimate as StateEstimate
from bus.odometry_content import _usable_covariance as _usable_covariance
from bus.odometry_content import odometry_of as odometry_of
from bus.odometry_content import pose_of as pose_of
from bus.odometry_wire import odometry_fields, odometry_frame

COMPONENT_ID = 191  # MAV_COMP_ID_ONBOARD_COMPUTER
SIGNING_EPOCH_S = 1420070400  # 2015-01-01T00:00:00Z
NEW_STREAM_TOLERANCE = 6_000_000  # 60 s in 10-us units, as in the MAVLink signing spec
FUTURE_TOLERANCE = 6_000_000  # 60 s in 10-us units
MAX_FRAME_BYTES = 280  # MAVLink 2: 10 header + 255 payload + 2 CRC + 13 signature
MAX_ACCUSED = 8  # neighbours one V2V broadcast may say its sender distrusts
ACCUSATION_FRAME_BYTES = 43  # a signed NAMED_VALUE_INT: 10 header + 18 payload + 2 CRC + 13 signature
MAX_V2V_BYTES = MAX_FRAME_BYTES + MAX_ACCUSED * ACCUSATION_FRAME_BYTES  # ODOMETRY and its accusations
DISTRUST = "distrust"  # the NAMED_VALUE_INT name of an accusation


@dataclass(frozen=True)
class Accusation:
    """NAMED_VALUE_INT "distrust": vehicle ``vehicle_id`` distrusts ``neighbour`` (its neighbour monitor's
    own verdict) as of ``time_boot_ms`` (the V2V epoch in ms, modulo 2^32)."""

    vehicle_id: int
    time_boot_ms: int
    neighbour: int


@dataclass(frozen=True)
class Heartbeat:
    vehicle_id: int
    mav_type: int
    system_status: int


def status_of(health: Health) -> EstimatorStatus:
    """ESTIMATOR_STATUS for an estimator's health: attitude, horizontal velocity and relative position
    always; absolute horizontal position while GNSS is trusted, the GPS glitch flag while it is not."""
    flags = mavlink2.ESTIMATOR_ATTITUDE | mavlink2.ESTIMATOR_VELOCITY_HORIZ | mavlink2.ESTIMATOR_POS_HORIZ_REL
    flags |= mavlink2.ESTIMATOR_POS_HORIZ_ABS if health.gnss_healthy else mavlink2.ESTIMATOR_GPS_GLITCH
    return EstimatorStatus(health.vehicle_id, health.stamp_us, flags, health.gnss_test_ratio, health.horizontal_sigma_m)


def signing_now() -> int:
    """The current MAVLink signing timestamp (10 us units since 2015-01-01)."""
    return int((time.time() - SIGNING_EPOCH_S) * 100_000)


def load_signing_key(raw: str | bytes) -> bytes:
    """A 32-byte key from 64 hex characters (str) or 32 raw bytes."""
    key = bytes.fromhex(raw.strip()) if isinstance(raw, str) else bytes(raw)
    if len(key) != 32:
        raise ValueError(f"a MAVLink signing key has 32 bytes, got {len(key)}")
    return key


@dataclass(frozen=True)
class EstimatorStatus:
    """ESTIMATOR_STATUS: solution flags (ESTIMATOR_GPS_GLITCH when GNSS is distrusted), the GNSS
    innovation test ratio (``pos_horiz_ratio``, PX4 convention: > 1 rejects) and 1-sigma horizontal accuracy."""

    vehicle_id: int
    time_usec: int
    flags: int
    pos_horiz_ratio: float
    pos_horiz_accuracy_m: float

    @property
    def gps_glitch(self) -> bool:
        return bool(self.flags & mavlink2.ESTIMATOR_GPS_GLITCH)


@dataclass(frozen=True)
class StatusText:
    vehicle_id: int
    severity: int
    text: str


@dataclass(frozen=True)
class SystemTime:
    """SYSTEM_TIME: the sender's time since its start (ms, modulo 2^32), sent just before each
    STATUSTEXT so that what the vehicle says is stamped with when it said it."""

    vehicle_id: int
    time_boot_ms: int


class MavlinkEncoder:
    """Packs one vehicle's MAVLink 2 stream (sysid = vehicle id, compid 191), signed if keyed."""

    def __init__(self, *, vehicle_id: int, signing_key: bytes | None = None, link_id: int = 0) -> None:
        self._mav = mavlink2.MAVLink(None, srcSystem=vehicle_id, srcComponent=COMPONENT_ID)
        if signing_key is not None:
            self._mav.signing.secret_key = signing_key
            self._mav.signing.sign_outgoing = True
            self._mav.signing.link_id = link_id

    def _pack(self, message: mavlink2.MAVLink_message) -> bytes:
        signing = self._mav.signing
        if signing.sign_outgoing:
            signing.timestamp = max(signing.timestamp, signing_now())
        frame = bytes(message.pack(self._mav))
        self._mav.seq = (self._mav.seq + 1) % 256  # pack() stamps the sequence number; send() would count it
        return frame

    def _pack_odometry(self, fields: tuple) -> bytes:
        """An ODOMETRY frame of ``fields`` in wire order (bus.odometry_wire), as ``_pack`` would pack it."""
        mav, signing = self._mav, self._mav.signing
        if signing.sign_outgoing:
            signing.timestamp = max(signing.timestamp, signing_now())
        frame = odometry_frame(
            fields, seq=mav.seq, sysid=mav.srcSystem, compid=mav.srcComponent, signing=signing.sign_outgoing and signing
        )
        mav.seq = (mav.seq + 1) % 256
        return frame

    def odometry(self, est: StateEstimate) -> bytes:
        half = 0.5 * est.yaw_rad
        quaternion = (float(np.cos(half)), 0.0, 0.0, float(np.sin(half)))  # w, x, y, z
        return self._pack_odometry(
            (est.time_usec, *map(float, est.position_m), *quaternion)
            + (*map(float, est.velocity_mps), 0.0, 0.0, float(est.yaw_rate_radps))
            + (*est.pose_covariance[_UPPER].tolist(), *est.velocity_covariance[_UPPER].tolist())
            + (_LOCAL_NED, _BODY_FRD, est.reset_counter % 256, est.estimator_type, 100)
        )

    def pose_odometry(self, estimate: PoseEstimate, *, altitude_m: float, reset_counter: int) -> bytes:
        """``odometry(odometry_of(estimate, ...))``, the same frame, packed straight from the planar estimate."""
        return self._pack_odometry(planar_fields(estimate, altitude_m=altitude_m, reset_counter=reset_counter))

    def no_estimate(self, time_usec: int, reset_counter: int = 0) -> bytes:
        """ODOMETRY saying "no estimate at ``time_usec``": NaN first pose covariance element, the rest zero."""
        unknown = (math.nan,) + (0.0,) * 20
        return self._pack_odometry(
            (time_usec, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
            + (0.0,) * 6
            + unknown
            + unknown
            + (_LOCAL_NED, _BODY_FRD, reset_counter % 256, mavlink2.MAV_ESTIMATOR_TYPE_GPS_INS, 0)
        )

    def estimator_status(self, status: EstimatorStatus) -> bytes:
        msg = self._mav.estimator_status_encode(
            status.time_usec,
            status.flags,
            0.0,
            float(status.pos_horiz_ratio),
            0.0,
            0.0,
            0.0,
            0.0,
            float(status.pos_horiz_accuracy_m),
            0.0,
        )
        return self._pack(msg)

    def statustext(self, severity: int, text: str) -> bytes:
        return self._pack(self._mav.statustext_encode(severity, text.encode()[:50]))

    def system_time(self, time_us: int) -> bytes:
        """SYSTEM_TIME at sim time ``time_us`` (time_boot_ms, modulo 2^32; no Unix time)."""
        return self._pack(self._mav.system_time_encode(0, (time_us // 1000) % 2**32))

    def accusation(self, time_usec: int, neighbour: int) -> bytes:
        """NAMED_VALUE_INT "distrust" = ``neighbour`` at the epoch ``time_usec`` (ms, modulo 2^32)."""
        msg = self._mav.named_value_int_encode((time_usec // 1000) % 2**32, DISTRUST.encode(), neighbour)
        return self._pack(msg)

    def heartbeat(self) -> bytes:
        msg = self._mav.heartbeat_encode(
            mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_GENERIC, 0, 0, mavlink2.MAV_STATE_ACTIVE
        )
        return self._pack(msg)


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
