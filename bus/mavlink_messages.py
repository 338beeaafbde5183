"""The MAVLink 2 messages a vehicle sends besides ODOMETRY (``bus.odometry_content``), as swarmloc
reads them: HEARTBEAT, ESTIMATOR_STATUS (``status_of`` a ``Health``), STATUSTEXT, SYSTEM_TIME and
an accusation (NAMED_VALUE_INT named "distrust"); the frame sizes a V2V broadcast may take; and the
signing clock (``signing_now``) and keys both the encoder (``bus.mavlink_codec``) and the decoder
(``bus.mavlink_decoder``) use."""

from __future__ import annotations

import time
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mavlink2

from bus.estimate import Health

COMPONENT_ID = 191  # MAV_COMP_ID_ONBOARD_COMPUTER
SIGNING_EPOCH_S = 1420070400  # 2015-01-01T00:00:00Z
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
