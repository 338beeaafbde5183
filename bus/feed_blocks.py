"""The sample blocks of a ``SensorBatch`` (bus.feed): their layout, and the checks a block passes
before a vehicle takes it, with numpy, or in plain Python for a block of a few rows.

A realtime tick's batch holds one to three rows a topic. numpy's calls are cheap once warm, but
a vehicle in realtime wakes fifty times a second among forty processes sharing two cores and runs
cold: a realtime batch decoded with numpy took 160 us in the vehicle against 20 us in a warm loop.
The same checks on the few raw values with ``struct`` touch much less code (measured cold: about
half): stamps, bounds, and each topic's own (2x2 covariances positive definite, ids, ranges and
bearings); a prior's 3x3 determinants stay numpy's. Both forms give one verdict and one message on
every block (property tests hold them together); what a block becomes is ``np.frombuffer`` of its
bytes either way.
"""

from __future__ import annotations

import struct
from typing import Any

import numpy as np

from bus import messages as m
from bus.errors import DecodeError
from bus.sensors import BY_TOPIC, SENSORS
from bus.spd import all_spd2, all_spd3, spd2_row
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
LAYOUT |= {sensor.topic: (sensor.width, sensor.max_rows, sensor.max_abs) for sensor in SENSORS}  # bus.sensors
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


def _flaw_small(
    stamps: tuple[int, ...], values: tuple[float, ...], stamp_us: int, max_abs: float, once: bool
) -> str | None:
    """``_flaw`` on a few rows' stamps and values (row-major), in Python."""
    pairs = tuple(zip(stamps, stamps[1:]))
    if stamps and (stamps[0] < max(0, stamp_us - MAX_TICK_US) or stamps[-1] > stamp_us):
        return "misplaced"
    if any(later < earlier for earlier, later in pairs):
        return "misplaced"
    if not all(-max_abs <= v <= max_abs for v in values):
        return "beyond"
    return "alike" if once and any(later == earlier for earlier, later in pairs) else None


_MESSAGES = {
    "misplaced": "stamps must be ordered and inside the tick ending at {stamp_us} us",
    "beyond": "values must be finite and within +-{max_abs:g}",
    "alike": "two samples with one stamp",
    "covariance": "covariance is not symmetric positive definite",
    "peer": "{who} ids must be other vehicles, 1-250",
    "landmark": f"ids must be integers 0-{MAX_LANDMARK_ID}",
    "sighting": "range must be >= 0 and the bearing within +-10 rad",
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
    added = BY_TOPIC.get(topic)
    once = topic not in SIGHTINGS and not (added is not None and added.several)
    if k <= SMALL_BLOCK_ROWS and topic is not Topic.PRIOR:
        values = struct.unpack(f"<{k * width}d", raw["data"])
        flaw = _flaw_small(struct.unpack(f"<{k}q", raw["stamp"]), values, stamp_us, max_abs, once)
        flaw = flaw or _topic_flaw_small(topic, values, width, vehicle_id)
    else:
        flaw = _flaw(stamps, rows, stamp_us, max_abs, once) or _topic_flaw(topic, rows, vehicle_id)
    if flaw is not None:
        who = "target" if topic is Topic.RANGING else "observer"
        raise DecodeError(f"{topic}: " + _MESSAGES[flaw].format(stamp_us=stamp_us, max_abs=max_abs, who=who))
    if added is not None and len(rows) and (own := added.flaw(rows)) is not None:
        raise DecodeError(f"{topic}: expected {own}")
    return stamps, seq0, rows


def _topic_flaw(topic: str, rows: np.ndarray, vehicle_id: int) -> str | None:
    """What is wrong with one topic's rows (k, width) beyond the common checks (finite values within
    bounds, by then), with numpy; None when nothing is."""
    if not len(rows):
        return None
    if topic in (Topic.GNSS, *SIGHTINGS) and not all_spd2(rows[:, -4:]):
        return "covariance"
    if topic is Topic.PRIOR and not all_spd3(rows[:, 3:]):
        return "covariance"
    if topic in (Topic.RANGING, Topic.SEEN):
        peer = rows[:, 0]
        if ((peer != np.round(peer)) | (peer < 1) | (peer > 250) | (peer == vehicle_id)).any():
            return "peer"
    if topic is Topic.LANDMARK:
        ident = rows[:, 0]
        if ((ident != np.round(ident)) | (ident < 0) | (ident > MAX_LANDMARK_ID)).any():
            return "landmark"
    if topic in SIGHTINGS and ((rows[:, 1] < 0) | (np.abs(rows[:, 2]) > 10.0)).any():
        return "sighting"
    return None


def _topic_flaw_small(topic: str, values: tuple[float, ...], width: int, vehicle_id: int) -> str | None:
    """``_topic_flaw`` on a few rows' values (row-major, ``width`` a row), in Python (not the prior,
    whose 3x3 determinants stay numpy's)."""
    rows = [values[i : i + width] for i in range(0, len(values), width)]
    if topic in (Topic.GNSS, *SIGHTINGS) and not all(spd2_row(*r[-4:]) for r in rows):
        return "covariance"
    if topic in (Topic.RANGING, Topic.SEEN) and any(
        p != round(p) or p < 1 or p > 250 or p == vehicle_id for p in (r[0] for r in rows)
    ):
        return "peer"
    if topic is Topic.LANDMARK and any(i != round(i) or i < 0 or i > MAX_LANDMARK_ID for i in (r[0] for r in rows)):
        return "landmark"
    if topic in SIGHTINGS and any(r[1] < 0 or abs(r[2]) > 10.0 for r in rows):
        return "sighting"
    return None
