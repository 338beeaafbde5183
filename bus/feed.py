"""Batched wire formats: every sample of one vehicle's sensors stamped in one clock tick in one
message (``SensorBatch`` on ``v/<id>/feed``), and the truth of every vehicle in one message per tick
(``TruthBatch`` on ``truth``).

Columnar msgpack: per topic a block ``{"stamp": <i8 bytes (k,)>, "seq0": int, "data": <f8 bytes (k, w)>}``
(sequence numbers of a topic are consecutive, so the first one is enough). Decoding validates
everything (shapes, finite values, ranges, stamps ordered and inside the tick, symmetric
positive-definite covariances; a block's checks in bus.feed_blocks) and raises DecodeError on any
fault; receivers unpack the rows into the per-sample messages of ``bus.messages`` and judge each
sample on its own (link faults).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import msgpack
import numpy as np

from bus import messages as m
from bus.errors import DecodeError
from bus.feed_blocks import (  # noqa: F401 (the layout is part of this module's interface)
    LAYOUT,
    MAX_LANDMARK_ID,
    MAX_SEQ,
    SIGHTINGS,
    TOPICS,
    block,
    column,
    int_field,
    outside_tick,
)
from bus.schema import WIRE_VERSION, unpack_tagged
from bus.sensors import SENSORS
from bus.topics import Topic

CAMERA_SIZES_PX = (8, 1024)  # frame side, inclusive bounds
MAX_CAMERA_FRAMES = 100  # per batch
MAX_METRES_PER_PIXEL = 100.0


@dataclass(frozen=True)
class CameraBlock:
    """Camera frames of one tick: stamps (k,) us, the first sequence number, ground scales (k,) m/px
    and pixels (k, size, size) uint8. On the wire: ``{"stamp": <i8 bytes>, "seq0": int, "size": int,
    "scale": <f8 bytes>, "pixels": <u1 bytes>}``."""

    stamps: np.ndarray
    seq0: int
    metres_per_pixel: np.ndarray
    pixels: np.ndarray


@dataclass(frozen=True)
class SensorBatch:
    """One vehicle's samples stamped in (stamp_us - tick length, stamp_us]: per topic, stamps (k,)
    in us, the first sequence number and rows (k, width) as in ``LAYOUT``. ``listeners``: the
    vehicles that range with this one in the tick, to which its V2V broadcasts of the tick's epochs
    go (None: to every vehicle; on the wire ``"listeners": [ids]``, distinct, 1-250, not its own)."""

    vehicle_id: int
    tick: int
    stamp_us: int
    blocks: dict[str, tuple[np.ndarray, int, np.ndarray]]
    camera: CameraBlock | None = None
    listeners: tuple[int, ...] | None = None

    def samples(self) -> list[tuple[Topic, Any]]:
        """(topic, message) for every sample, in stamp order (topics in LAYOUT order, then camera
        frames, at equal stamps)."""
        out = []
        vid = self.vehicle_id
        for name, (stamps, seq0, rows) in self.blocks.items():
            topic, make = _TOPICS[name], _MAKERS[name]
            out += [(topic, make(vid, int(s), seq0 + i, r)) for i, (s, r) in enumerate(zip(stamps.tolist(), rows))]
        if self.camera is not None:
            c = self.camera
            out += [
                (Topic.CAMERA, m.CameraFrame(vid, int(s), c.seq0 + i, c.pixels[i], float(c.metres_per_pixel[i])))
                for i, s in enumerate(c.stamps.tolist())
            ]
        out.sort(key=lambda item: item[1].stamp_us)  # stable: LAYOUT order among equal stamps
        return out

    def message(self, topic: str, i: int) -> Any:
        """The ``i``-th sample of ``topic`` (``Topic.CAMERA``: the ``i``-th frame) as its message."""
        if topic == Topic.CAMERA:
            c = self.camera
            return m.CameraFrame(
                self.vehicle_id, int(c.stamps[i]), c.seq0 + i, c.pixels[i], float(c.metres_per_pixel[i])
            )
        stamps, seq0, rows = self.blocks[topic]
        return _MAKERS[topic](self.vehicle_id, int(stamps[i]), seq0 + i, rows[i])

    def count(self) -> int:
        """How many samples and camera frames the batch carries."""
        return sum(len(b[0]) for b in self.blocks.values()) + (len(self.camera.stamps) if self.camera else 0)


def _prior(vid: int, stamp: int, seq: int, r: np.ndarray) -> m.PosePrior:
    return m.PosePrior(vid, stamp, seq, r[:3].copy(), r[3:].reshape(3, 3).copy())


def _imu(vid: int, stamp: int, seq: int, r: np.ndarray) -> m.ImuSample:
    return m.ImuSample(vid, stamp, seq, r[:3], r[3:])


def _odom(vid: int, stamp: int, seq: int, r: np.ndarray) -> m.WheelOdometry:
    return m.WheelOdometry(vid, stamp, seq, float(r[0]), float(r[1]))


def _gnss(vid: int, stamp: int, seq: int, r: np.ndarray) -> m.GnssFix:
    return m.GnssFix(vid, stamp, seq, r[:2], r[2:].reshape(2, 2))


def _ranging(vid: int, stamp: int, seq: int, r: np.ndarray) -> m.RangeBearing:
    return m.RangeBearing(vid, stamp, seq, int(r[0]), float(r[1]), float(r[2]), r[3:].reshape(2, 2))


def _seen(vid: int, stamp: int, seq: int, r: np.ndarray) -> m.SeenBy:
    return m.SeenBy(vid, stamp, seq, int(r[0]), float(r[1]), float(r[2]), r[3:].reshape(2, 2))


def _landmark(vid: int, stamp: int, seq: int, r: np.ndarray) -> m.LandmarkSighting:
    return m.LandmarkSighting(vid, stamp, seq, int(r[0]), float(r[1]), float(r[2]), r[3:].reshape(2, 2))


_MAKERS = {
    Topic.PRIOR: _prior,
    Topic.IMU: _imu,
    Topic.ODOM: _odom,
    Topic.GNSS: _gnss,
    Topic.RANGING: _ranging,
    Topic.SEEN: _seen,
    Topic.LANDMARK: _landmark,
}
_MAKERS |= {sensor.topic: sensor.message for sensor in SENSORS}  # the sensors added by the recipe (bus.sensors)
_TOPICS = {**{t.value: t for t in Topic}, **{sensor.topic: sensor.topic for sensor in SENSORS}}


def encode_batch(batch: SensorBatch) -> bytes:
    body: dict[str, Any] = {
        "type": "SensorBatch",
        "v": WIRE_VERSION,
        "vehicle_id": batch.vehicle_id,
        "tick": batch.tick,
        "stamp_us": batch.stamp_us,
    }
    for topic, (stamps, seq0, rows) in batch.blocks.items():
        body[topic] = {
            "stamp": np.ascontiguousarray(stamps, "<i8").tobytes(),
            "seq0": int(seq0),
            "data": np.ascontiguousarray(rows, "<f8").tobytes(),
        }
    if batch.camera is not None:
        c = batch.camera
        body[Topic.CAMERA] = {
            "stamp": np.ascontiguousarray(c.stamps, "<i8").tobytes(),
            "seq0": int(c.seq0),
            "size": int(c.pixels.shape[1]) if c.pixels.ndim == 3 else 0,
            "scale": np.ascontiguousarray(c.metres_per_pixel, "<f8").tobytes(),
            "pixels": np.ascontiguousarray(c.pixels, np.uint8).tobytes(),
        }
    if batch.listeners is not None:
        body["listeners"] = [int(j) for j in batch.listeners]
    return msgpack.packb(body, use_bin_type=True)


def _camera_block(raw: Any, stamp_us: int) -> CameraBlock:
    """Shape checks only (square frames of a sane size, one scale per frame, stamps in the tick):
    what a frame shows is for the vehicle's front end to judge."""
    if not isinstance(raw, dict) or raw.keys() != {"stamp", "seq0", "size", "scale", "pixels"}:
        raise DecodeError("camera: expected a block with stamp, seq0, size, scale and pixels")
    stamps = column(raw["stamp"], "<i8", "camera.stamp")
    scale = column(raw["scale"], "<f8", "camera.scale")
    size = int_field(raw, "size", *CAMERA_SIZES_PX)
    seq0 = int_field(raw, "seq0", 0, MAX_SEQ)
    pixels = raw["pixels"]
    k = len(stamps)
    if not isinstance(pixels, bytes) or k > MAX_CAMERA_FRAMES or len(scale) != k or len(pixels) != k * size * size:
        raise DecodeError(
            f"camera: {k} frames of {size} x {size} px need {k} scales and {k * size * size} "
            f"pixel bytes (at most {MAX_CAMERA_FRAMES} frames)"
        )
    if outside_tick(stamps, stamp_us, strictly=True):
        raise DecodeError(f"camera: stamps must be increasing and inside the tick ending at {stamp_us} us")
    if not np.all((scale > 0) & (scale <= MAX_METRES_PER_PIXEL)):
        raise DecodeError(f"camera: ground scale must be in (0, {MAX_METRES_PER_PIXEL:g}] m per pixel")
    return CameraBlock(stamps, seq0, scale, np.frombuffer(pixels, np.uint8).reshape(k, size, size))


def decode_batch(payload: bytes) -> SensorBatch:
    """Validate a SensorBatch; DecodeError names the first problem."""
    body = unpack_tagged(payload, "SensorBatch")
    allowed = {"type", "v", "vehicle_id", "tick", "stamp_us", Topic.CAMERA, "listeners", *TOPICS}
    if not set(body) <= allowed or not {"vehicle_id", "tick", "stamp_us"} <= set(body):
        raise DecodeError(f"SensorBatch: fields must be {sorted(allowed)}")
    vid = int_field(body, "vehicle_id", 1, 250)
    tick = int_field(body, "tick", 0, 2**53)
    stamp_us = int_field(body, "stamp_us", 0, 2**53)
    blocks = {t: block(t, body[t], vid, stamp_us) for t in TOPICS if t in body}
    camera = _camera_block(body[Topic.CAMERA], stamp_us) if Topic.CAMERA in body else None
    listeners = _listeners(body["listeners"], vid) if "listeners" in body else None
    return SensorBatch(vid, tick, stamp_us, blocks, camera, listeners)


def _listeners(value: Any, vid: int) -> tuple[int, ...]:
    """The listeners field: a list of distinct vehicle ids 1-250 other than the batch's own."""
    if (
        not isinstance(value, list)
        or len(value) > 250
        or not all(isinstance(j, int) and not isinstance(j, bool) and 1 <= j <= 250 for j in value)
    ):
        raise DecodeError("listeners: expected a list of vehicle ids 1-250")
    if len(set(value)) != len(value) or vid in value:
        raise DecodeError("listeners: ids must be distinct and not the batch's own vehicle")
    return tuple(value)


TRUTH_WIDTH = 6  # x m, y m, theta rad, speed m/s, yaw rate rad/s, height above the launch point m
MAX_TRUTH_BYTES = 1 << 20  # the largest truth batch the ground station takes (one tick, every vehicle)


def truth_batch_bytes(truth_rate_hz: float, tick_s: float, vehicles: int) -> int:
    """About how many bytes one tick's TruthBatch takes on the wire: its rows of float64 and its
    stamps, with a tenth more for the ranging pairs and the envelope (measured: 529 kB for 250
    vehicles, 50 Hz and 1 s, where the rows are 500 kB)."""
    rows = round(truth_rate_hz * tick_s)
    return round(1.1 * rows * (vehicles * TRUTH_WIDTH + 1) * 8)


@dataclass(frozen=True)
class TruthBatch:
    """Truth of every vehicle at the truth stamps of one tick: stamps (k,) us, vehicle ids (n,),
    rows (k, n, 6) [x, y, theta, speed, yaw rate, height]; a row of NaN where a vehicle has no truth (a
    replayed data set's gaps); the pairs (m, 2) [observer, target] of vehicles that ranged in the
    tick (for the live view's ranging lines). The height (m, up) is above the point the vehicle
    launched from, the origin of the altitude its ODOMETRY's local NED frame carries (as PX4's local
    frame starts at the vehicle's home): 0 for a world that flies level."""

    tick: int
    stamp_us: int
    stamps_us: np.ndarray
    vehicle_ids: np.ndarray
    rows: np.ndarray
    pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))  # (m, 2) [observer, target]


def encode_truth(batch: TruthBatch) -> bytes:
    return msgpack.packb(
        {
            "type": "TruthBatch",
            "v": WIRE_VERSION,
            "tick": batch.tick,
            "stamp_us": batch.stamp_us,
            "stamps": np.ascontiguousarray(batch.stamps_us, "<i8").tobytes(),
            "ids": np.ascontiguousarray(batch.vehicle_ids, "<i8").tobytes(),
            "data": np.ascontiguousarray(batch.rows, "<f8").tobytes(),
            "pairs": np.ascontiguousarray(batch.pairs, "<i8").tobytes(),
        },
        use_bin_type=True,
    )


def decode_truth(payload: bytes) -> TruthBatch:
    body = unpack_tagged(payload, "TruthBatch")
    if set(body) != {"type", "v", "tick", "stamp_us", "stamps", "ids", "data", "pairs"}:
        raise DecodeError("TruthBatch: fields must be type, v, tick, stamp_us, stamps, ids, data, pairs")
    tick, stamp_us = int_field(body, "tick", 0, 2**53), int_field(body, "stamp_us", 0, 2**53)
    stamps, ids = column(body["stamps"], "<i8", "stamps"), column(body["ids"], "<i8", "ids")
    data = column(body["data"], "<f8", "data")
    k, n = len(stamps), len(ids)
    if n > 250 or k > 1000 or len(data) != k * n * TRUTH_WIDTH:
        raise DecodeError(f"TruthBatch: {k} stamps x {n} vehicles need {k * n * TRUTH_WIDTH} values")
    if np.any(ids < 1) or np.any(ids > 250) or len(set(ids.tolist())) != n:
        raise DecodeError("TruthBatch: vehicle ids must be distinct, 1-250")
    if outside_tick(stamps, stamp_us, strictly=True):
        raise DecodeError("TruthBatch: stamps must increase inside the tick")
    rows = data.reshape(k, n, TRUTH_WIDTH)
    gap = np.all(np.isnan(rows), axis=2, keepdims=True)  # no truth for that vehicle at that stamp
    if not np.all((np.abs(rows) <= m.MAX_POSITION_M) | gap):
        raise DecodeError("TruthBatch: values must be finite (no truth at a stamp: a whole row of NaN)")
    pairs = column(body["pairs"], "<i8", "pairs")
    if len(pairs) % 2 or len(pairs) > 2 * n * n:
        raise DecodeError(f"TruthBatch: pairs must be (observer, target) pairs of the {n} vehicles")
    pairs = pairs.reshape(-1, 2)
    if not np.all(np.isin(pairs, ids)) or np.any(pairs[:, 0] == pairs[:, 1]):
        raise DecodeError("TruthBatch: a ranging pair must name two different vehicles of the batch")
    return TruthBatch(tick, stamp_us, stamps, ids, rows, pairs)
