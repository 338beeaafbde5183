"""The sample blocks of a ``SensorBatch`` (bus.feed): their layout, and the checks a block passes
before a vehicle takes it, with numpy, or in plain Python for a block of a few rows.

A realtime tick's batch holds one to three rows a topic. numpy's calls are cheap once warm, but
a vehicle in realtime wakes fifty times a second among forty processes sharing two cores and runs
cold: a realtime batch decoded with numpy took 160 us in the vehicle against 20 us in a warm loop.
The same checks on the few raw values with ``struct`` touch much less code (measured cold: about
half). Both forms give one verdict and one message on every block (a property test holds them
together); what a block becomes is ``np.frombuffer`` of its bytes either way.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from bus import messages as m
from bus.errors import DecodeError
from bus.topics import Topic

MAX_TICK_US = 1_000_000
MAX_SEQ = 2**62
# topic: (row width, max rows per batch, max |value|)
LAYOUT = {
    Topic.PRIOR: (12, 1, m.MAX_POSITION_M),  # pose (3), covariance (3, 3)
    Topic.IMU: (6, 1000, 1000.0),  # gyro (3) rad/s, accel (3) m/s^2
    Topic.ODOM: (2, 1000, 1000.0),  # speed m/s, yaw rate rad/s
    Topic.GNSS: (6, 100, m.MAX_POSITION_M),  # position (2), covariance (2, 2)
    Topic.RANGING: (7, 2500, 1e6),  # target id, range m, bearing rad, covariance (2, 2)
    Topic.SEEN: (7, 2500, 1e6),  # observer id, range m, bearing rad, covariance (2, 2)
    Topic.LANDMARK: (7, 2500, 1e6),  # landmark id, range m, bearing rad, covariance (2, 2)
}
SIGHTINGS = (Topic.RANGING, Topic.SEEN, Topic.LANDMARK)  # several per stamp (one camera frame sees many)
MAX_LANDMARK_ID = 999_999
TOPICS = tuple(LAYOUT)
SMALL_BLOCK_ROWS = 8  # a block of at most this many rows is checked in plain Python


def int_field(body: dict, name: str, lo: int, hi: int) -> int:
    value = body.get(name)
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise DecodeError(f"{name}: expected an integer in [{lo}, {hi}]")
    return value


def column(raw: Any, dtype: str, name: str) -> np.ndarray:
    if not isinstance(raw, bytes) or len(raw) % 8:
        raise DecodeError(f"{name}: expected raw 8-byte values")
    return np.frombuffer(raw, dtype=dtype)


def _spd2(c: np.ndarray) -> bool:
    """All rows (k, 4) are symmetric positive-definite 2x2 matrices (row-major)."""
    a, b, cc, d = c[:, 0], c[:, 1], c[:, 2], c[:, 3]
    return bool(
        (np.abs(b - cc) <= 1e-9 * np.maximum(np.abs(b), 1e-300)).all() and (a > 0).all() and (a * d - b * cc > 0).all()
    )


def _spd3(c: np.ndarray) -> bool:
    """All rows (k, 9) are symmetric positive-definite 3x3 matrices (Sylvester's criterion)."""
    M = c.reshape(-1, 3, 3)
    if not np.allclose(M, np.transpose(M, (0, 2, 1)), rtol=1e-9, atol=0.0):
        return False
    return bool((M[:, 0, 0] > 0).all() and (np.linalg.det(M[:, :2, :2]) > 0).all() and (np.linalg.det(M) > 0).all())


def outside_tick(stamps: np.ndarray, stamp_us: int, *, strictly: bool) -> bool:
    """Stamps (k,) us not all inside the tick ending at ``stamp_us``, or out of order (``strictly``:
    also two equal). Compared, never subtracted: int64 differences wrap."""
    if not len(stamps):
        return False
    earlier, later = stamps[:-1], stamps[1:]
    backwards = (later <= earlier) if strictly else (later < earlier)
    return bool(stamps[0] < max(0, stamp_us - MAX_TICK_US) or stamps[-1] > stamp_us or backwards.any())


def _flaw(stamps: np.ndarray, rows: np.ndarray, stamp_us: int, max_abs: float, once: bool) -> str | None:
    """What is wrong with a block's stamps (k,) us and rows (k, w), checked with numpy: stamps out of
    order or outside the tick, a value beyond +-``max_abs`` (NaN and inf too), or (``once``: one
    sample per stamp) two samples with one stamp; None when nothing is."""
    outside = outside_tick(stamps, stamp_us, strictly=once)  # one pass where all is well
    if outside and (not once or outside_tick(stamps, stamp_us, strictly=False)):
        return "misplaced"
    if len(stamps) and not np.abs(rows).max() <= max_abs:
        return "beyond"
    return "alike" if outside else None


def _flaw_small(stamp_bytes: bytes, data_bytes: bytes, stamp_us: int, max_abs: float, once: bool) -> str | None:
    """``_flaw`` on a few rows' raw little-endian bytes (int64 stamps, float64 values), in Python."""
    stamps = struct.unpack(f"<{len(stamp_bytes) // 8}q", stamp_bytes)
    pairs = tuple(zip(stamps, stamps[1:]))
    if stamps and (stamps[0] < max(0, stamp_us - MAX_TICK_US) or stamps[-1] > stamp_us):
        return "misplaced"
    if any(later < earlier for earlier, later in pairs):
        return "misplaced"
    if not all(-max_abs <= v <= max_abs for v in struct.unpack(f"<{len(data_bytes) // 8}d", data_bytes)):
        return "beyond"
    return "alike" if once and any(later == earlier for earlier, later in pairs) else None


_MESSAGES = {
    "misplaced": "stamps must be ordered and inside the tick ending at {stamp_us} us",
    "beyond": "values must be finite and within +-{max_abs:g}",
    "alike": "two samples with one stamp",
}


def block(topic: str, raw: Any, vehicle_id: int, stamp_us: int) -> tuple[np.ndarray, int, np.ndarray]:
    """A batch's block of ``topic`` for vehicle ``vehicle_id``, checked: stamps (k,) us, the first
    sequence number, rows (k, width) as in ``LAYOUT``; DecodeError names the first fault."""
    width, max_rows, max_abs = LAYOUT[topic]
    if not isinstance(raw, dict) or raw.keys() != {"stamp", "seq0", "data"}:
        raise DecodeError(f"{topic}: expected a block with stamp, seq0 and data")
    stamps = column(raw["stamp"], "<i8", f"{topic}.stamp")
    rows = column(raw["data"], "<f8", f"{topic}.data")
    k = len(stamps)
    if k > max_rows or len(rows) != k * width:
        raise DecodeError(f"{topic}: {k} stamps need {k * width} values (at most {max_rows} rows), got {len(rows)}")
    seq0 = int_field(raw, "seq0", 0, MAX_SEQ)
    rows = rows.reshape(k, width)
    once = topic not in SIGHTINGS
    if k <= SMALL_BLOCK_ROWS:
        flaw = _flaw_small(raw["stamp"], raw["data"], stamp_us, max_abs, once)
    else:
        flaw = _flaw(stamps, rows, stamp_us, max_abs, once)
    if flaw is not None:
        raise DecodeError(f"{topic}: " + _MESSAGES[flaw].format(stamp_us=stamp_us, max_abs=max_abs))
    _check_topic(topic, rows, vehicle_id)
    return stamps, seq0, rows


def _check_topic(topic: str, rows: np.ndarray, vehicle_id: int) -> None:
    """The checks of one topic's rows (k, width) beyond the common ones."""
    if not len(rows):
        return
    if topic in (Topic.GNSS, *SIGHTINGS) and not _spd2(rows[:, -4:]):
        raise DecodeError(f"{topic}: covariance is not symmetric positive definite")
    if topic is Topic.PRIOR and not _spd3(rows[:, 3:]):
        raise DecodeError("prior: covariance is not symmetric positive definite")
    if topic in (Topic.RANGING, Topic.SEEN):
        peer = rows[:, 0]
        if ((peer != np.round(peer)) | (peer < 1) | (peer > 250) | (peer == vehicle_id)).any():
            who = "target" if topic is Topic.RANGING else "observer"
            raise DecodeError(f"{topic}: {who} ids must be other vehicles, 1-250")
    if topic is Topic.LANDMARK:
        ident = rows[:, 0]
        if ((ident != np.round(ident)) | (ident < 0) | (ident > MAX_LANDMARK_ID)).any():
            raise DecodeError(f"landmark: ids must be integers 0-{MAX_LANDMARK_ID}")
    if topic in SIGHTINGS and ((rows[:, 1] < 0) | (np.abs(rows[:, 2]) > 10.0)).any():
        raise DecodeError(f"{topic}: range must be >= 0 and the bearing within +-10 rad")
