"""Typed messages that cross the bus as msgpack (sensor feeds, truth, clock, acks, status).

Units are in the field names; times are simulation time in integer microseconds. Frames: the world
is local NED at constant altitude, so ``x`` points north, ``y`` east, heading ``theta`` is measured
from north towards east (rad).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

import numpy as np

from bus.consistency import NIS_FIELDS, NIS_KINDS
from bus.rejections import REASONS
from bus.schema import Array, Bool, Counts, Covariance, Float, Floats, Int, Text, decode, encode

VehicleId = Annotated[int, Int(1, 250)]
StampUs = Annotated[int, Int(0, 2**53)]
Seq = Annotated[int, Int(0, 2**63 - 1)]
MAX_POSITION_M = 1e7

__all__ = [
    "ImuSample",
    "WheelOdometry",
    "GnssFix",
    "PosePrior",
    "RangeBearing",
    "SeenBy",
    "LandmarkSighting",
    "Truth",
    "ClockTick",
    "TickAck",
    "GroundStationAck",
    "VehicleStatus",
    "RunEnd",
    "encode",
    "decode",
]
Rejected = Annotated[tuple[int, ...], Counts(len(REASONS))]


@dataclass(frozen=True)
class ImuSample:
    """Body-frame gyro (rad/s) and specific force (m/s^2), each shape (3,)."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    seq: Seq
    gyro_radps: Annotated[np.ndarray, Array((3,), 100.0)]
    accel_mps2: Annotated[np.ndarray, Array((3,), 1000.0)]


@dataclass(frozen=True)
class WheelOdometry:
    """Measured forward speed (m/s) and yaw rate (rad/s)."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    seq: Seq
    speed_mps: Annotated[float, Float(1000.0)]
    yaw_rate_radps: Annotated[float, Float(100.0)]


@dataclass(frozen=True)
class GnssFix:
    """Horizontal position fix (m, shape (2,)) with its reported covariance (m^2, (2, 2))."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    seq: Seq
    position_m: Annotated[np.ndarray, Array((2,), MAX_POSITION_M)]
    covariance_m2: Annotated[np.ndarray, Covariance((2, 2), 1e8)]


@dataclass(frozen=True)
class PosePrior:
    """Surveyed start pose ``[x_m, y_m, theta_rad]`` with covariance (3, 3), given at launch."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    seq: Seq
    pose: Annotated[np.ndarray, Array((3,), MAX_POSITION_M)]
    covariance: Annotated[np.ndarray, Covariance((3, 3), 1e8)]


@dataclass(frozen=True)
class Truth:
    """True pose ``[x_m, y_m, theta_rad]``, speed (m/s) and yaw rate (rad/s)."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    seq: Seq
    pose: Annotated[np.ndarray, Array((3,), MAX_POSITION_M)]
    speed_mps: Annotated[float, Float(1000.0)]
    yaw_rate_radps: Annotated[float, Float(100.0)]


@dataclass(frozen=True)
class RangeBearing:
    """Radio ranging to another vehicle: range (m) and bearing (rad, from the heading, positive
    towards east) of ``target_id`` seen from ``vehicle_id``, covariance (2, 2) over [range, bearing]."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    seq: Seq
    target_id: VehicleId
    range_m: Annotated[float, Float(1e6)]
    bearing_rad: Annotated[float, Float(10.0)]
    covariance: Annotated[np.ndarray, Covariance((2, 2), 1e8)]


@dataclass(frozen=True)
class SeenBy:
    """A neighbour's sighting of this vehicle, relayed to it: range (m) and bearing (rad, from the
    observer's heading) of ``vehicle_id`` seen from ``observer_id``, covariance (2, 2) over [range,
    bearing]. The seen vehicle fuses it with the observer's broadcast pose (vehicle.models.cooperative)."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    seq: Seq
    observer_id: VehicleId
    range_m: Annotated[float, Float(1e6)]
    bearing_rad: Annotated[float, Float(10.0)]
    covariance: Annotated[np.ndarray, Covariance((2, 2), 1e8)]


@dataclass(frozen=True)
class LandmarkSighting:
    """A camera sighting of a mapped landmark: its id (a data set's subject number), range (m) and
    bearing (rad, from the heading) seen from ``vehicle_id``, covariance (2, 2) over [range, bearing]."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    seq: Seq
    landmark_id: Annotated[int, Int(0, 999_999)]
    range_m: Annotated[float, Float(1e6)]
    bearing_rad: Annotated[float, Float(10.0)]
    covariance: Annotated[np.ndarray, Covariance((2, 2), 1e8)]


@dataclass(frozen=True)
class CameraFrame:
    """A down-looking camera frame: grey pixels (H, W) uint8, forward up (row 0), left at column 0,
    the centre pixel below the vehicle; ``metres_per_pixel`` is the ground scale. Travels only inside
    a ``bus.feed.SensorBatch`` (raw bytes); the vehicle's front end judges the contents."""

    vehicle_id: int
    stamp_us: int
    seq: int
    pixels: np.ndarray
    metres_per_pixel: float


@dataclass(frozen=True)
class ClockTick:
    """World clock: every vehicle's sensor batch for this tick (stamps up to ``stamp_us``) has been
    published before it.

    ``wall_ns`` is the world's wall clock at publication; ``final`` marks the end of the run.
    ``v2v_published`` counts, per vehicle (entry id - 1), the V2V broadcasts to every vehicle it had
    sent by its last acknowledgement: in lockstep a vehicle waits until it has heard them all before
    it cycles on, so what it fuses never depends on how the bus interleaves keys (frames sent to the
    vehicles that range their sender alone are waited for one by one: ``running``).
    ``members`` lists the vehicles the world waits for (each acknowledged the previous tick, or is
    rejoining): in lockstep the ground station scores up to where all of them have published, so
    the order of metrics.csv never depends on when it hears their liveliness.
    ``running`` lists the members that acknowledged the previous tick: each runs every cycle of this
    one and broadcasts at every V2V epoch in it, so a neighbour may wait for those broadcasts.
    """

    tick: Annotated[int, Int(0, 2**53)]
    stamp_us: StampUs
    wall_ns: Annotated[int, Int(0, 2**63 - 1)]
    final: Annotated[bool, Bool()]
    v2v_published: Annotated[tuple[int, ...], Counts(250)] = ()
    members: Annotated[tuple[int, ...], Counts(250, 250)] = ()
    running: Annotated[tuple[int, ...], Counts(250, 250)] = ()


@dataclass(frozen=True)
class TickAck:
    """A vehicle has processed everything up to ``tick`` (lockstep mode) and had sent ``v2v_sent``
    V2V broadcasts by then."""

    vehicle_id: VehicleId
    tick: Annotated[int, Int(0, 2**53)]
    v2v_sent: Annotated[int, Int(0, 2**53)] = 0


@dataclass(frozen=True)
class GroundStationAck:
    """The ground station has handled every clock tick up to ``tick`` (lockstep flow control)."""

    tick: Annotated[int, Int(0, 2**53)]


@dataclass(frozen=True)
class VehicleStatus:
    """Loop statistics a vehicle reports about itself (cumulative since start)."""

    vehicle_id: VehicleId
    stamp_us: StampUs
    cycles: Annotated[int, Int(0, 2**53)]
    overruns: Annotated[int, Int(0, 2**53)]
    jitter_p99_us: Annotated[float, Float(1e12)]
    cycle_p99_us: Annotated[float, Float(1e12)]
    dropped_stale: Annotated[int, Int(0, 2**53)]
    rejected_gnss: Annotated[int, Int(0, 2**53)]
    decode_errors: Annotated[int, Int(0, 2**53)]
    reset_counter: Annotated[int, Int(0, 255)]
    duplicates: Annotated[int, Int(0, 2**53)] = 0
    samples_lost: Annotated[int, Int(0, 2**53)] = 0
    late_fused: Annotated[int, Int(0, 2**53)] = 0
    v2v_fused: Annotated[int, Int(0, 2**53)] = 0
    v2v_missing: Annotated[int, Int(0, 2**53)] = 0
    rejected: Rejected = ()
    replays: Annotated[int, Int(0, 2**53)] = 0
    final: Annotated[bool, Bool()] = False  # the last status, sent with the final tick's acknowledgement
    landmarks: Annotated[int, Int(0, 2**31)] = 0  # SLAM: landmarks in the map
    landmarks_updated: Annotated[int, Int(0, 2**31)] = 0  # SLAM: landmarks the last usable frame updated
    frames_used: Annotated[int, Int(0, 2**53)] = 0  # SLAM: camera frames through the front end
    nis: Annotated[tuple[float, ...], Floats((0, NIS_FIELDS * len(NIS_KINDS)), 1e15)] = ()  # bus.consistency.NisBook
    loop_priority: Annotated[int, Int(0, 99)] = 0  # realtime: the SCHED_FIFO priority granted, 0 the fair scheduler
    v2v_received: Annotated[int, Int(0, 2**53)] = 0  # V2V frames the bus delivered to it (inbound)


@dataclass(frozen=True)
class RunEnd:
    """The world has finished: every vehicle acknowledged the final tick (or was declared dead), or
    the run was cut short (``status``: complete, groundstation-lost, interrupted). ``completed``: the
    vehicles that acknowledged the final tick (they had sent everything before). ``rejected``: the
    world's rejected input by reason (order of bus.rejections.REASONS)."""

    tick: Annotated[int, Int(0, 2**53)]
    stamp_us: StampUs
    vehicles_alive: Annotated[int, Int(0, 250)]
    status: Annotated[str, Text(40)] = "complete"
    rejected: Rejected = ()
    completed: Annotated[tuple[int, ...], Counts(250, 250)] = ()
