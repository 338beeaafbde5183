"""A SLAM vehicle's map on the wire: landmark positions (m, 2) [m] and their 2 x 2 position
covariances [m^2], stamped in sim time; a 3-D map (ar-ekf-slam-3d) adds each landmark's height [m,
up, in the vehicle's frame: from its launch point] and the rest of its 3 x 3 covariance. It travels
on the vehicle's status key (``v/<id>/status``), just before each status (1 Hz) and the final one:
zenoh keeps order within a key, so the ground station holds the last map when the final status
arrives. For the report and the live view to draw.

msgpack ``{"type": "LandmarkMap", "v": .., "vehicle_id": int, "stamp_us": int, "xy": <f8 bytes
(m, 2)>, "cov": <f8 bytes (m, 3) as [xx, xy, yy]>}``, and for a 3-D map both of ``"z": <f8 bytes
(m,)>`` and ``"cov_z": <f8 bytes (m, 3) as [xz, yz, zz]>``. Decoding is total: DecodeError names the
first problem (types, sizes, finite values, positive-definite covariances, 2 x 2 or 3 x 3).
"""

from __future__ import annotations

from dataclasses import dataclass

import msgpack
import numpy as np

from bus.errors import DecodeError
from bus.schema import WIRE_VERSION, Int, unpack_tagged
from bus.spd import all_spd2, all_spd3

MAX_LANDMARKS = 5000
MAX_COORD_M = 1e7
MAX_MAP_BYTES = 512 << 10  # a 3-D map of MAX_LANDMARKS: 72 bytes each
PLANAR_FIELDS = {"type", "v", "vehicle_id", "stamp_us", "xy", "cov"}


@dataclass(frozen=True)
class LandmarkMap:
    vehicle_id: int
    stamp_us: int
    xy_m: np.ndarray  # (m, 2)
    covariance_m2: np.ndarray  # (m, 2, 2)
    height_m: np.ndarray | None = None  # (m,) up, a 3-D map's; None for a map on the ground
    covariance3_m2: np.ndarray | None = None  # (m, 3, 3) of [x, y, up], a 3-D map's (its [:2, :2] is covariance_m2)


def _packed(cov: np.ndarray) -> np.ndarray:
    """Covariances (m, 2, 2) as rows (m, 3) [xx, xy, yy]."""
    return np.stack([cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1]], axis=1) if len(cov) else np.zeros((0, 3))


def _packed_up(cov3: np.ndarray) -> np.ndarray:
    """The height's column of covariances (m, 3, 3) as rows (m, 3) [xz, yz, zz]."""
    return np.ascontiguousarray(cov3[:, :, 2]) if len(cov3) else np.zeros((0, 3))


def encode_map(lmap: LandmarkMap) -> bytes:
    packed = _packed(lmap.covariance_m2)
    body = {
        "type": "LandmarkMap",
        "v": WIRE_VERSION,
        "vehicle_id": int(lmap.vehicle_id),
        "stamp_us": int(lmap.stamp_us),
        "xy": np.ascontiguousarray(lmap.xy_m, "<f8").tobytes(),
        "cov": np.ascontiguousarray(packed, "<f8").tobytes(),
    }
    if lmap.height_m is not None and lmap.covariance3_m2 is not None:
        body["z"] = np.ascontiguousarray(lmap.height_m, "<f8").tobytes()
        body["cov_z"] = np.ascontiguousarray(_packed_up(lmap.covariance3_m2), "<f8").tobytes()
    return msgpack.packb(body, use_bin_type=True)


def _floats(body: dict, name: str, width: int) -> np.ndarray:
    raw = body.get(name)
    if not isinstance(raw, bytes) or len(raw) % (8 * width) or len(raw) > 8 * width * MAX_LANDMARKS:
        raise DecodeError(f"LandmarkMap.{name}: expected rows of {width} 8-byte floats (at most {MAX_LANDMARKS})")
    return np.frombuffer(raw, "<f8").reshape(-1, width)


def decode_map(payload: bytes) -> LandmarkMap:
    """Validate a LandmarkMap; DecodeError names the first problem."""
    body = unpack_tagged(payload, "LandmarkMap", MAX_MAP_BYTES)
    if body.keys() - {"z", "cov_z"} != PLANAR_FIELDS or len(body.keys() & {"z", "cov_z"}) == 1:
        raise DecodeError(
            "LandmarkMap: fields must be type, v, vehicle_id, stamp_us, xy and cov, and both or neither of z and cov_z"
        )
    vid = Int(1, 250).unpack("LandmarkMap.vehicle_id", body["vehicle_id"])
    stamp = Int(0, 2**53).unpack("LandmarkMap.stamp_us", body["stamp_us"])
    xy, cov = _floats(body, "xy", 2), _floats(body, "cov", 3)
    if len(xy) != len(cov):
        raise DecodeError(f"LandmarkMap: {len(xy)} positions but {len(cov)} covariances")
    if not np.all(np.abs(xy) <= MAX_COORD_M) or not np.all(np.abs(cov) <= MAX_COORD_M**2):
        raise DecodeError("LandmarkMap: values must be finite and in range")
    a, b, d = cov[:, 0], cov[:, 1], cov[:, 2]
    if not all_spd2(np.stack([a, b, b, d], axis=1)):
        raise DecodeError("LandmarkMap: covariances must be positive definite")
    full = np.stack([np.stack([a, b], axis=1), np.stack([b, d], axis=1)], axis=1)
    if "z" not in body:
        return LandmarkMap(vid, stamp, xy.copy(), full)
    height, up = _floats(body, "z", 1)[:, 0], _floats(body, "cov_z", 3)
    if len(height) != len(xy) or len(up) != len(xy):
        raise DecodeError(f"LandmarkMap: {len(xy)} positions but {len(height)} heights and {len(up)} rows of cov_z")
    if not np.all(np.abs(height) <= MAX_COORD_M) or not np.all(np.abs(up) <= MAX_COORD_M**2):
        raise DecodeError("LandmarkMap: heights and cov_z must be finite and in range")
    cov3 = np.zeros((len(xy), 3, 3))
    cov3[:, :2, :2], cov3[:, :, 2], cov3[:, 2, :] = full, up, up
    if len(cov3) and not all_spd3(cov3.reshape(-1, 9)):
        raise DecodeError("LandmarkMap: 3-D covariances must be positive definite")
    return LandmarkMap(vid, stamp, xy.copy(), full, height.copy(), cov3)


def map_record(lmap: LandmarkMap) -> dict:
    """The map as JSON for the run directory (``map_v<id>.json``): stamp, positions, covariances
    ([xx, xy, yy]); a 3-D map's heights (``z_m``, up) and the rest of its covariances (``cov_z_m2``:
    [xz, yz, zz])."""
    return {
        "vehicle": lmap.vehicle_id,
        "t_s": round(lmap.stamp_us * 1e-6, 6),
        "landmarks": len(lmap.xy_m),
        "xy_m": np.round(lmap.xy_m, 4).tolist(),
        "cov_m2": np.round(_packed(lmap.covariance_m2), 8).tolist(),
    } | (
        {}
        if lmap.height_m is None
        else {
            "z_m": np.round(lmap.height_m, 4).tolist(),
            "cov_z_m2": np.round(_packed_up(lmap.covariance3_m2), 8).tolist(),
        }
    )
