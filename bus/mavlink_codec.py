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
of 10 us since 2015-01-01 and a truncated SHA-256 signature. Incoming frames are verified by
``bus.mavlink_decoder`` rather than by pymavlink, because pymavlink 2.4.50 stores a stream's
timestamp *before* checking the signature: one forged frame with a far-future timestamp would make
every genuine frame look like a replay. We check the signature first, refuse timestamps more than
60 s ahead of our clock (so even a key holder cannot freeze a stream), and only then advance the
stream's timestamp.

Contents are checked too (``bus.odometry_content``): an ODOMETRY whose [x, y, yaw] covariance is not
symmetric positive definite, or is absurdly large, or whose values are not finite, is rejected as
degenerate.

This module packs a vehicle's stream (``MavlinkEncoder``); reading is ``bus.mavlink_decoder``'s, the
other messages and the signing clock ``bus.mavlink_messages``'s (their names re-exported here).
"""

from __future__ import annotations

import math

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from bus.errors import MavlinkRejected as MavlinkRejected
from bus.estimate import PoseEstimate
from bus.mavlink_decoder import MavlinkDecoder as MavlinkDecoder
from bus.mavlink_decoder import frame_header as frame_header
from bus.mavlink_decoder import split_frames as split_frames
from bus.mavlink_messages import ACCUSATION_FRAME_BYTES as ACCUSATION_FRAME_BYTES
from bus.mavlink_messages import COMPONENT_ID, DISTRUST, EstimatorStatus, signing_now
from bus.mavlink_messages import MAX_ACCUSED as MAX_ACCUSED
from bus.mavlink_messages import MAX_V2V_BYTES as MAX_V2V_BYTES
from bus.mavlink_messages import Accusation as Accusation
from bus.mavlink_messages import Heartbeat as Heartbeat
from bus.mavlink_messages import StatusText as StatusText
from bus.mavlink_messages import SystemTime as SystemTime
from bus.mavlink_messages import load_signing_key as load_signing_key
from bus.mavlink_messages import status_of as status_of
from bus.odometry_content import _BODY_FRD, _LOCAL_NED, _UPPER, planar_fields
from bus.odometry_content import MAX_VARIANCE as MAX_VARIANCE
from bus.odometry_content import NoEstimate as NoEstimate
from bus.odometry_content import StateEstimate as StateEstimate
from bus.odometry_content import _usable_covariance as _usable_covariance
from bus.odometry_content import odometry_of as odometry_of
from bus.odometry_content import pose_of as pose_of
from bus.odometry_wire import odometry_frame


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
