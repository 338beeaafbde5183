"""A SLAM vehicle's map on the wire: landmark positions (m, 2) [m] and their 2 x 2 position
covariances [m^2], stamped in sim time. It travels on the vehicle's status key (``v/<id>/status``),
just before each status (1 Hz) and the final one: zenoh keeps order within a key, so the ground
station holds the last map when the final status arrives. For the report to draw.

msgpack ``{"type": "LandmarkMap", "v": .., "vehicle_id": int, "stamp_us": int, "xy": <f8 bytes
(m, 2)>, "cov": <f8 bytes (m, 3) as [xx, xy, yy]>}``. Decoding is total: DecodeError names the
first problem (types, sizes, finite values, positive-definite covariances).
"""

from __future__ import annotations

from dataclasses import dataclass

import msgpack
import numpy as np

from bus.errors import DecodeError
from bus.schema import WIRE_VERSION

MAX_LANDMARKS = 5000
MAX_COORD_M = 1e7
MAX_MAP_BYTES = 256 << 10


@dataclass(frozen=True)
class LandmarkMap:
    vehicle_id: int
    stamp_us: int
    xy_m: np.ndarray        # (m, 2)
    covariance_m2: np.ndarray  # (m, 2, 2)


def encode_map(lmap: LandmarkMap) -> bytes:
    c = lmap.covariance_m2
    packed = np.stack([c[:, 0, 0], c[:, 0, 1], c[:, 1, 1]], axis=1) if len(c) else np.zeros((0, 3))
    return msgpack.packb({"type": "LandmarkMap", "v": WIRE_VERSION, "vehicle_id": int(lmap.vehicle_id),
                          "stamp_us": int(lmap.stamp_us), "xy": np.ascontiguousarray(lmap.xy_m, "<f8").tobytes(),
                          "cov": np.ascontiguousarray(packed, "<f8").tobytes()}, use_bin_type=True)


def _int(body: dict, name: str, lo: int, hi: int) -> int:
    value = body.get(name)
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise DecodeError(f"LandmarkMap.{name}: expected an integer in [{lo}, {hi}]")
    return value


def _floats(body: dict, name: str, width: int) -> np.ndarray:
    raw = body.get(name)
    if not isinstance(raw, bytes) or len(raw) % (8 * width) or len(raw) > 8 * width * MAX_LANDMARKS:
        raise DecodeError(f"LandmarkMap.{name}: expected rows of {width} 8-byte floats (at most {MAX_LANDMARKS})")
    return np.frombuffer(raw, "<f8").reshape(-1, width)


def decode_map(payload: bytes) -> LandmarkMap:
    """Validate a LandmarkMap; DecodeError names the first problem."""
    if not isinstance(payload, (bytes, bytearray)) or len(payload) > MAX_MAP_BYTES:
        raise DecodeError(f"LandmarkMap: payload must be bytes of at most {MAX_MAP_BYTES}")
    try:
        body = msgpack.unpackb(bytes(payload), raw=False, strict_map_key=True)
    except Exception as exc:  # msgpack raises many types on garbage
        raise DecodeError(f"LandmarkMap: not valid msgpack ({type(exc).__name__})") from None
    if not isinstance(body, dict) or body.keys() != {"type", "v", "vehicle_id", "stamp_us", "xy", "cov"} \
            or body["type"] != "LandmarkMap" or body["v"] != WIRE_VERSION:
        raise DecodeError("LandmarkMap: wrong fields, type tag or version")
    vid, stamp = _int(body, "vehicle_id", 1, 250), _int(body, "stamp_us", 0, 2**53)
    xy, cov = _floats(body, "xy", 2), _floats(body, "cov", 3)
    if len(xy) != len(cov):
        raise DecodeError(f"LandmarkMap: {len(xy)} positions but {len(cov)} covariances")
    if not np.all(np.abs(xy) <= MAX_COORD_M) or not np.all(np.abs(cov) <= MAX_COORD_M**2):
        raise DecodeError("LandmarkMap: values must be finite and in range")
    a, b, d = cov[:, 0], cov[:, 1], cov[:, 2]
    if not np.all((a > 0) & (a * d - b * b > 0)):
        raise DecodeError("LandmarkMap: covariances must be positive definite")
    full = np.stack([np.stack([a, b], axis=1), np.stack([b, d], axis=1)], axis=1)
    return LandmarkMap(vid, stamp, xy.copy(), full)


def map_record(lmap: LandmarkMap) -> dict:
    """The map as JSON for the run directory (``map_v<id>.json``): stamp, positions, covariances."""
    c = lmap.covariance_m2
    return {"vehicle": lmap.vehicle_id, "t_s": round(lmap.stamp_us * 1e-6, 6), "landmarks": len(lmap.xy_m),
            "xy_m": np.round(lmap.xy_m, 4).tolist(),
            "cov_m2": np.round(np.stack([c[:, 0, 0], c[:, 0, 1], c[:, 1, 1]], axis=1), 8).tolist() if len(c) else []}
