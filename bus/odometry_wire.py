"""ODOMETRY frames read straight from the wire: the same fields, checks and values as pymavlink's
``MAVLink.decode`` (MAVLink 2: header, length, CRC with the message's CRC extra, a payload trimmed of
trailing zeros padded back, the wire order of its fields), without making a message object.

Every vehicle reads its neighbours' broadcasts and the ground station every vehicle's stream: this
was a third of the ground station's time. A frame that is anything but a well-formed MAVLink 2
ODOMETRY gets None, and goes to pymavlink (which decodes it or says what is wrong with it).
"""

from __future__ import annotations

import hashlib
import struct
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

_ODOMETRY = mavlink2.MAVLink_odometry_message
_PAYLOAD = _ODOMETRY.unpacker  # the wire order: time_usec, x, y, z, q (4), vx, vy, vz, rates (3), 21 + 21, 5 bytes
_HEADER_BYTES, _CRC_BYTES = 10, 2
_HEADER = struct.Struct("<BBBBBBBHB")  # marker, length, flags (2), seq, sysid, compid, msgid (3 bytes)
_CRC = struct.Struct("<H")
_SIGNATURE_HEAD = struct.Struct("<BQ")  # link id, 48-bit timestamp (the first 7 bytes)


def odometry_fields(frame: bytes) -> tuple | None:
    """The wire fields (61,) of a MAVLink 2 ODOMETRY ``frame`` whose length and CRC check out, in
    wire order (the constants at the end name their places), or None for any other frame."""
    n = len(frame)
    if n < _HEADER_BYTES + _CRC_BYTES or frame[0] != mavlink2.PROTOCOL_MARKER_V2:
        return None
    if frame[7] | (frame[8] << 8) | (frame[9] << 16) != _ODOMETRY.id:
        return None
    signature = mavlink2.MAVLINK_SIGNATURE_BLOCK_LEN if frame[2] & mavlink2.MAVLINK_IFLAG_SIGNED else 0
    end = n - _CRC_BYTES - signature
    if frame[1] != end - _HEADER_BYTES:
        return None
    crc = mavlink2.x25crc(bytes(frame[1:end]) + bytes((_ODOMETRY.crc_extra,))).crc
    if crc != frame[end] | (frame[end + 1] << 8):
        return None
    payload = bytes(frame[_HEADER_BYTES:end]).ljust(_PAYLOAD.size, b"\0")[: _PAYLOAD.size]
    return _PAYLOAD.unpack(payload)


def odometry_frame(fields: tuple, *, seq: int, sysid: int, compid: int, signing: Any = None) -> bytes:
    """The MAVLink 2 ODOMETRY frame of ``fields`` in wire order, as pymavlink's ``pack`` makes it: the
    payload's trailing zeros trimmed (one byte kept), CRC with the CRC extra, and signed when
    ``signing`` (pymavlink's ``MAVLinkSigning``: key, link id, timestamp, which moves on by one)."""
    payload = _PAYLOAD.pack(*fields)
    payload = payload[: max(1, len(payload.rstrip(b"\0")))]
    flags = mavlink2.MAVLINK_IFLAG_SIGNED if signing else 0
    msgid = _ODOMETRY.id
    frame = _HEADER.pack(
        mavlink2.PROTOCOL_MARKER_V2, len(payload), flags, 0, seq, sysid, compid, msgid & 0xFFFF, msgid >> 16
    )
    frame += payload
    frame += _CRC.pack(mavlink2.x25crc(frame[1:] + bytes((_ODOMETRY.crc_extra,))).crc)
    if signing:
        frame += _SIGNATURE_HEAD.pack(signing.link_id, signing.timestamp)[:7]
        frame += hashlib.sha256(signing.secret_key + frame).digest()[:6]
        signing.timestamp += 1
    return frame


# where each field sits in odometry_fields' tuple
TIME_USEC, X, Y, Z, Q, VX, VY, VZ, YAWSPEED = 0, 1, 2, 3, slice(4, 8), 8, 9, 10, 13
POSE_COVARIANCE, VELOCITY_COVARIANCE, RESET_COUNTER, ESTIMATOR_TYPE = slice(14, 35), slice(35, 56), 58, 59
