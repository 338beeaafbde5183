"""The pure world: N unicycles at constant altitude and their sensors, stepped in integer microseconds.

``World.advance(until_us)`` returns the encoded messages, in stamp order, for every step up to
``until_us``. The node publishes them; tests and Monte Carlo runs use the world with no bus.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bus import messages as m
from bus.config import SwarmConfig
from bus.keys import KeySpace
from sim import sensors
from sim.physical_faults import PhysicalFaults
from sim.kinematics import unicycle_step
from sim.trajectories import make_trajectory, start_pads


@dataclass
class _Vehicle:
    vehicle_id: int
    trajectory: object
    rng: np.random.Generator
    gyro_bias: np.ndarray
    ranging_rng: np.random.Generator
    last_speed_mps: float = 0.0
    seq: dict[str, int] = field(default_factory=dict)

    def next_seq(self, topic: str) -> int:
        self.seq[topic] = self.seq.get(topic, -1) + 1
        return self.seq[topic]


def _period_us(rate_hz: float) -> int:
    return round(1e6 / rate_hz)


class World:
    """Truth and sensor generation for every vehicle of ``config``; deterministic from its seed."""

    def __init__(self, config: SwarmConfig) -> None:
        self.config = config
        self.keys = KeySpace(config.bus.prefix)
        self.step_us = _period_us(config.sensors.imu_rate_hz)
        self.now_us = -self.step_us  # nothing emitted yet; the first step is stamped 0
        spec, wc = config.sensors, config.world
        pads = start_pads(wc.vehicles, wc.spacing_m)
        self.vehicles: list[_Vehicle] = []
        poses = []
        for index in range(wc.vehicles):
            vid = index + 1
            layout_rng = np.random.default_rng([wc.seed, vid, 1])
            kind = wc.trajectories[index % len(wc.trajectories)]
            trajectory, start = make_trajectory(kind, centre_m=pads[index], speed_mps=wc.speed_mps,
                                                radius_m=wc.radius_m, rng=layout_rng)
            rng = np.random.default_rng([wc.seed, vid])
            self.vehicles.append(_Vehicle(vid, trajectory, rng, sensors.initial_gyro_bias(spec, rng),
                                          np.random.default_rng([wc.seed, vid, 2])))
            poses.append(start)
        self.poses = np.array(poses)
        self.faults = PhysicalFaults(config.faults)

    def vehicle_ids(self) -> list[int]:
        return [v.vehicle_id for v in self.vehicles]

    def published(self) -> tuple[int, ...]:
        """Samples published so far per vehicle and feed, in the layout of ``ClockTick.published``."""
        return tuple(v.seq.get(feed, -1) + 1 for v in self.vehicles for feed in m.FEEDS)

    def comm_jammed(self, t_us: int) -> tuple[int, ...]:
        """Vehicles inside an active comm-jamming zone at ``t_us`` (their V2V traffic is lost)."""
        return tuple(v.vehicle_id for v, pose in zip(self.vehicles, self.poses)
                     if self.faults.comm_jammed(t_us, pose))

    def advance(self, until_us: int) -> list[tuple[str, bytes]]:
        """Emit every step stamped in (now, until_us]; returns (key, payload) pairs in stamp order."""
        out: list[tuple[str, bytes]] = []
        while self.now_us + self.step_us <= until_us:
            self.now_us += self.step_us
            out.extend(self._step(self.now_us))
        return out

    def _due(self, stamp_us: int, rate_hz: float) -> bool:
        return stamp_us % _period_us(rate_hz) == 0

    def _step(self, t_us: int) -> list[tuple[str, bytes]]:
        """Sample every sensor at ``t_us`` from the current poses, then move the poses one step."""
        spec, dt = self.config.sensors, self.step_us * 1e-6
        inputs = np.array([v.trajectory.inputs(t_us * 1e-6, pose) for v, pose in zip(self.vehicles, self.poses)])
        out: list[tuple[str, bytes]] = []
        jammed = set(self.comm_jammed(t_us)) if self._due(t_us, spec.ranging_rate_hz) else set()
        for vehicle, pose, (speed, yaw_rate) in zip(self.vehicles, self.poses, inputs):
            out.extend(self._samples(vehicle, t_us, pose, float(speed), float(yaw_rate)))
            if self._due(t_us, spec.ranging_rate_hz):
                out.extend(self._ranging(vehicle, t_us, pose, jammed))
            vehicle.gyro_bias = sensors.walk_gyro_bias(vehicle.gyro_bias, spec, dt, vehicle.rng)
        self.poses = unicycle_step(self.poses, inputs[:, 0], inputs[:, 1], dt)
        return out

    def _ranging(self, v: _Vehicle, t_us: int, pose: np.ndarray, jammed: set[int]) -> list[tuple[str, bytes]]:
        """Radio ranging to every other vehicle in reach; nothing to or from a comm-jammed vehicle.
        Noise is drawn for every pair, so faults and distances never shift the noise stream."""
        spec, out = self.config.sensors, []
        silent = v.vehicle_id in jammed or self.faults.silenced(v.vehicle_id, "ranging", t_us, pose)
        for other, other_pose in zip(self.vehicles, self.poses):
            if other is v:
                continue
            rng_m, bearing, cov = sensors.range_bearing(pose, other_pose[:2], spec, v.ranging_rng)
            if silent or other.vehicle_id in jammed or rng_m > spec.ranging_max_m:
                continue
            msg = m.RangeBearing(v.vehicle_id, t_us, v.next_seq("ranging"), other.vehicle_id, rng_m, bearing, cov)
            out.append((self.keys.sensor(v.vehicle_id, "ranging"), m.encode(msg)))
        return out

    def _samples(self, v: _Vehicle, t_us: int, pose: np.ndarray, speed: float, yaw_rate: float) -> list[tuple[str, bytes]]:
        spec, vid, keys, out = self.config.sensors, v.vehicle_id, self.keys, []
        if t_us == 0:
            prior, cov = sensors.pose_prior(pose, spec, v.rng)
            out.append((keys.sensor(vid, "prior"), m.encode(m.PosePrior(vid, t_us, v.next_seq("prior"), prior, cov))))
        if self._due(t_us, spec.truth_rate_hz):
            truth = m.Truth(vid, t_us, v.next_seq("truth"), pose.copy(), speed, yaw_rate)
            out.append((keys.truth(vid), m.encode(truth)))
        accel_fwd = (speed - v.last_speed_mps) / (self.step_us * 1e-6) if t_us else 0.0
        v.last_speed_mps = speed
        gyro, accel = sensors.imu_sample(speed, accel_fwd, yaw_rate, v.gyro_bias, spec, v.rng)
        if not self.faults.silenced(vid, "imu", t_us, pose):
            out.append((keys.sensor(vid, "imu"), m.encode(m.ImuSample(vid, t_us, v.next_seq("imu"), gyro, accel))))
        if self._due(t_us, spec.odom_rate_hz):
            measured = sensors.odometry_sample(speed, yaw_rate, spec, v.rng)
            if not self.faults.silenced(vid, "odom", t_us, pose):
                out.append((keys.sensor(vid, "odom"), m.encode(m.WheelOdometry(vid, t_us, v.next_seq("odom"), *measured))))
        if self._due(t_us, spec.gnss_rate_hz):
            fix, cov = sensors.gnss_fix(pose[:2], spec, v.rng)  # drawn even when jammed: faults never shift the noise
            if not self.faults.silenced(vid, "gnss", t_us, pose):
                fix = fix + self.faults.spoof_offset_m(vid, t_us, pose)
                out.append((keys.sensor(vid, "gnss"), m.encode(m.GnssFix(vid, t_us, v.next_seq("gnss"), fix, cov))))
        return out
