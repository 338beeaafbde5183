"""The pure world: N unicycles at constant altitude and their sensors, stepped in integer microseconds.

``World.advance(until_us)`` runs every IMU step up to ``until_us`` and returns what was measured:
per vehicle the sensor rows of each topic (``bus.feed`` layout) and the truth of every vehicle. The
node publishes them as one batch per vehicle per tick; tests and Monte Carlo runs use the world with
no bus. Noise comes from each vehicle's own generators in blocks (``sim.noise_blocks``), so the
output never depends on how time is cut into ticks, and faults never shift the noise streams.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from bus.config import SwarmConfig
from bus.pads import start_pads
from bus.topics import Topic
from sim import sensors
from sim.added_sensors import AddedSensors
from sim.high_rate import HighRateSensors, ImuSteps, StepRows
from sim.kinematics import unicycle_arcs
from sim.noise_blocks import BLOCK_STEPS, ahead_schedule, next_block
from sim.physical_faults import PhysicalFaults
from sim.trajectories import make_trajectory
from sim.true_errors import TrueErrors, wobble, wobble_tones
from sim.world_output import TickOutput

if TYPE_CHECKING:
    from sim.terrain import Terrain


@dataclass
class _Vehicle:
    vehicle_id: int
    trajectory: object
    rng: np.random.Generator
    ranging_rng: np.random.Generator
    camera_rng: np.random.Generator
    errors: TrueErrors
    seq: dict[str, int] = field(default_factory=dict)
    noise: dict[str, np.ndarray] = field(default_factory=dict)
    ahead: tuple[dict, dict] | None = None  # the next block's (noise, error draws), drawn ahead

    def next_seq(self, topic: str) -> int:
        self.seq[topic] = self.seq.get(topic, -1) + 1
        return self.seq[topic]


def _period_us(rate_hz: float) -> int:
    return round(1e6 / rate_hz)


def gnss_offset_us(phase: float, period_us: int, step_us: int) -> int:
    """When in its period of ``period_us`` a GNSS fix comes (``sensors.gnss_phase``, a share of the
    period), to the nearest world step of ``step_us``."""
    return round(phase * period_us / step_us) * step_us % period_us


class World:
    """Truth and sensor generation for every vehicle of ``config``; deterministic from its seed."""

    def __init__(self, config: SwarmConfig) -> None:
        self.config = config
        self.step_us = _period_us(config.sensors.imu_rate_hz)
        self.steps_done = 0  # IMU steps emitted; the next one is stamped steps_done * step_us
        spec, wc = config.sensors, config.world
        pads = start_pads(wc.vehicles, wc.spacing_m)
        self.vehicles: list[_Vehicle] = []
        poses, tones, biases = [], [], []
        for index in range(wc.vehicles):
            vid = index + 1
            layout_rng = np.random.default_rng([wc.seed, vid, 1])
            kind = wc.trajectories[index % len(wc.trajectories)]
            trajectory, start = make_trajectory(
                kind, centre_m=pads[index], speed_mps=wc.speed_mps, radius_m=wc.radius_m, rng=layout_rng
            )
            rng, errors_rng = np.random.default_rng([wc.seed, vid]), np.random.default_rng([wc.seed, vid, 4])
            biases.append(sensors.initial_gyro_bias(spec, rng))
            tones.append(wobble_tones(wc.sensor_truth, errors_rng))
            self.vehicles.append(
                _Vehicle(
                    vid,
                    trajectory,
                    rng,
                    np.random.default_rng([wc.seed, vid, 2]),
                    np.random.default_rng([wc.seed, vid, 3]),
                    TrueErrors.draw(wc.sensor_truth, errors_rng),
                )
            )
            poses.append(start)
        self.poses = np.array(poses)
        self._wobble = tuple(np.array(part) for part in zip(*tones))  # (N, 2, tones) x 2, (N, 2, 1)
        self._wobbles = bool(wc.sensor_truth.wobble_speed_mps or wc.sensor_truth.wobble_yaw_rate_radps)
        self._wobble_block: np.ndarray | None = None  # the current block's wobble (_wobble_over), when wobbling
        self.faults = PhysicalFaults(config.faults)
        self._ahead_at = {k: [self.vehicles[i] for i in ids] for k, ids in ahead_schedule(len(self.vehicles)).items()}
        self._periods = {
            topic: _period_us(rate)
            for topic, rate in (
                (Topic.ODOM, spec.odom_rate_hz),
                (Topic.GNSS, spec.gnss_rate_hz),
                (Topic.RANGING, spec.ranging_rate_hz),
                ("truth", spec.truth_rate_hz),
            )
        }
        self._gnss_offset_us = gnss_offset_us(spec.gnss_phase, self._periods[Topic.GNSS], self.step_us)
        odom_scale = np.array([v.errors.odom_scale for v in self.vehicles])
        self.high_rate = HighRateSensors(
            np.array(biases), odom_scale, self.step_us, self._periods[Topic.ODOM], wc.sensor_truth
        )
        self.terrain: Terrain | None = None
        if spec.camera_rate_hz:  # OpenCV and the terrain only for a camera swarm
            import cv2

            from sim.terrain import make_terrain

            self.terrain = make_terrain(config)
            cv2.setNumThreads(1)  # frames are small: OpenCV's thread pool costs more than it brings
        if self.terrain is not None:
            self._periods[Topic.CAMERA] = _period_us(spec.camera_rate_hz)
        self.added = AddedSensors(config, self.vehicle_ids(), self.step_us)  # bus.sensors
        self._height_over: Callable[[np.ndarray], np.ndarray] | None = None  # set for UAVs over relief
        if spec.camera3d.rate_hz:  # the relief (and OpenCV) only for a 3-D camera swarm
            from sim.sensor_models.camera3d import height_above_launch

            self._height_over = partial(height_above_launch, launch_xy=self.poses[:, :2].copy())

    @property
    def now_us(self) -> int:
        """Stamp of the last step emitted (-step_us before the first)."""
        return (self.steps_done - 1) * self.step_us

    def vehicle_ids(self) -> list[int]:
        return [v.vehicle_id for v in self.vehicles]

    def comm_jammed(self, t_us: int) -> tuple[int, ...]:
        """Vehicles inside an active comm-jamming zone at ``t_us`` (their V2V traffic is lost)."""
        return tuple(v.vehicle_id for v, pose in zip(self.vehicles, self.poses) if self.faults.comm_jammed(t_us, pose))

    def advance(self, until_us: int) -> TickOutput:
        """Run every step stamped in (now, until_us]."""
        out = TickOutput({v.vehicle_id: {} for v in self.vehicles}, [], [])
        streams = {Topic.IMU: ImuSteps(), Topic.ODOM: StepRows()}
        while self.steps_done * self.step_us <= until_us:
            self._step(out, streams)
        for topic, step_rows in streams.items():
            for v, (stamps, rows) in zip(self.vehicles, step_rows.per_vehicle(len(self.vehicles))):
                if len(stamps):
                    seq0 = v.seq.get(topic, -1) + 1
                    v.seq[topic] = seq0 + len(stamps) - 1
                    out.streams.setdefault(v.vehicle_id, {})[topic] = (stamps, seq0, rows)
        return out

    def _draw_block(self, v: _Vehicle) -> None:
        """One vehicle's noise for the block starting now: drawn ahead, or drawn now (the first block)."""
        v.noise, v.errors.block = v.ahead or self._next_block(v)
        v.ahead = None

    def _next_block(self, v: _Vehicle) -> tuple[dict, dict]:
        wc = self.config.world
        return next_block(
            self.config.sensors, wc.sensor_truth, self.step_us, wc.vehicles, v.rng, v.ranging_rng, v.errors
        )

    def _step(self, out: TickOutput, streams: dict[str, StepRows]) -> None:
        """Sample every sensor at the step's stamp from the current poses, then move the poses."""
        t_us, k = self.steps_done * self.step_us, self.steps_done % BLOCK_STEPS
        spec, dt = self.config.sensors, self.step_us * 1e-6
        if k == 0:
            for v in self.vehicles:
                self._draw_block(v)
            self.high_rate.new_block([v.noise for v in self.vehicles], [v.errors.block for v in self.vehicles])
            if self._wobbles:
                self._wobble_block = self._wobble_over(t_us)
        for v in self._ahead_at.get(k, ()):
            v.ahead = self._next_block(v)
        law = np.array([v.trajectory.inputs(t_us * 1e-6, pose) for v, pose in zip(self.vehicles, self.poses)])
        inputs = law + self._wobble_block[k, 0] if self._wobbles else law
        if t_us % self._periods["truth"] == 0:
            out.truth_stamps.append(t_us)
            out.truth.append(np.column_stack([self.poses, inputs, self._heights()]))
        self.high_rate.step(streams, t_us, k, inputs[:, 0], inputs[:, 1], self._silenced)
        camera_due = self.terrain is not None and t_us % self._periods[Topic.CAMERA] == 0
        if t_us == 0 or self._gnss_due(t_us) or camera_due:
            for v, pose in zip(self.vehicles, self.poses):
                self._samples(out.rows[v.vehicle_id], v, t_us, k, pose)
        if t_us % self._periods[Topic.RANGING] == 0 and spec.ranging_max_m > 0 and spec.ranging_max_peers > 0:
            self._ranging(out, t_us, k)
        if self.added.topics:
            silenced, emit = partial(self._added_silenced, t_us), partial(self._emit_added, out, t_us)
            self.added.measure(t_us, self.vehicle_ids(), self.poses, silenced, emit)
        self._move(law, k, dt)
        self.steps_done += 1

    def _heights(self) -> np.ndarray:
        """Every vehicle's height (N,) m above its launch point: a UAV's over the relief (the 3-D
        camera's world), 0 in a world that flies level."""
        if self._height_over is None:
            return np.zeros(len(self.vehicles))
        return self._height_over(self.poses[:, :2])

    def _gnss_due(self, t_us: int) -> bool:
        return (t_us - self._gnss_offset_us) % self._periods[Topic.GNSS] == 0

    def _wobble_over(self, t_us: int) -> np.ndarray:
        """The input wobble (BLOCK_STEPS, substeps, N, 2) [m/s, rad/s] at every substep of the block of
        steps starting at ``t_us`` (substep 0: the step's own stamp)."""
        substeps = self.config.world.sensor_truth.substeps
        times_us = [
            [round(t_us + k * self.step_us + s * self.step_us / substeps) for s in range(substeps)]
            for k in range(BLOCK_STEPS)
        ]
        return wobble(np.array(times_us)[..., None, None] * 1e-6, *self._wobble)

    def _move(self, law: np.ndarray, k: int, dt: float) -> None:
        """Integrate the poses over step ``k`` of the block in ``sensor_truth.substeps`` arcs, the
        inputs varying from one to the next (finer than any filter, which holds sampled inputs)."""
        inputs = law + self._wobble_block[k] if self._wobbles else law[None]  # (substeps, N, 2)
        self.poses = unicycle_arcs(self.poses, inputs[..., 0], inputs[..., 1], dt / inputs.shape[0])

    def _added_silenced(self, t_us: int, vehicle_id: int, topic: str) -> bool:
        i = self.vehicle_ids().index(vehicle_id)
        return self.faults.silenced(vehicle_id, topic, t_us, self.poses[i])

    def _emit_added(self, out: TickOutput, t_us: int, vehicle_id: int, topic: str, row: np.ndarray) -> None:
        v = self.vehicles[self.vehicle_ids().index(vehicle_id)]
        self._emit(out.rows[vehicle_id], v, topic, t_us, row)

    def _emit(self, rows: dict, v: _Vehicle, topic: str, t_us: int, row: np.ndarray) -> None:
        rows.setdefault(topic, []).append((t_us, v.next_seq(topic), row))

    def _silenced(self, topic: str, t_us: int) -> np.ndarray | None:
        """Which vehicles' ``topic`` produces nothing at ``t_us`` (N,); None: no fault silences any."""
        if not self.faults.faults:
            return None
        return np.array([self.faults.silenced(v.vehicle_id, topic, t_us, p) for v, p in zip(self.vehicles, self.poses)])

    def _samples(self, rows: dict, v: _Vehicle, t_us: int, k: int, pose: np.ndarray) -> None:
        """One vehicle's prior (at 0), GNSS fix and camera frame when due."""
        spec, vid, silenced = self.config.sensors, v.vehicle_id, self.faults.silenced
        if t_us == 0:
            prior, cov = sensors.pose_prior(pose, spec, v.rng)
            self._emit(rows, v, Topic.PRIOR, t_us, np.concatenate([prior, cov.ravel()]))
        if self._gnss_due(t_us):
            error = v.errors.gnss_error(k, self._periods[Topic.GNSS] * 1e-6, v.noise[Topic.GNSS][k])
            if not silenced(vid, Topic.GNSS, t_us, pose):
                fix = pose[:2] + error + self.faults.spoof_offset_m(vid, t_us, pose)
                self._emit(rows, v, Topic.GNSS, t_us, np.concatenate([fix, (np.eye(2) * spec.gnss_sigma_m**2).ravel()]))
        if (
            self.terrain is not None
            and t_us % self._periods[Topic.CAMERA] == 0
            and not silenced(vid, Topic.CAMERA, t_us, pose)
        ):
            from sim.camera import camera_frame

            frame = camera_frame(
                self.terrain, pose, v.camera_rng, size_px=spec.camera_size_px, noise_sigma=spec.camera_noise_grey
            )
            self._emit(rows, v, Topic.CAMERA, t_us, (self.terrain.metres_per_pixel, frame))

    def _ranging(self, out: TickOutput, t_us: int, k: int) -> None:
        """Radio ranging from every vehicle to its ``ranging_max_peers`` nearest peers in reach;
        nothing to or from a comm-jammed vehicle. Noise is drawn for every pair, so faults and
        distances never shift the noise stream."""
        spec = self.config.sensors
        jammed = set(self.comm_jammed(t_us))
        xy = self.poses[:, :2]
        dist = np.hypot(*(xy[None, :, :] - xy[:, None, :]).transpose(2, 0, 1))
        cov = np.array([spec.range_sigma_m**2, 0.0, 0.0, spec.bearing_sigma_rad**2])
        reachable = (dist <= spec.ranging_max_m) & ~np.eye(len(xy), dtype=bool)
        reachable[:, [j for j, v in enumerate(self.vehicles) if v.vehicle_id in jammed]] = False
        for i, v in enumerate(self.vehicles):
            if v.vehicle_id in jammed or self.faults.silenced(v.vehicle_id, Topic.RANGING, t_us, self.poses[i]):
                continue
            order = np.argsort(dist[i], kind="stable")
            candidates = order[reachable[i, order]]  # in reach, nearest first (ties by index)
            for j in sorted(candidates[: spec.ranging_max_peers].tolist()):
                noise = v.noise[Topic.RANGING][k, j] * v.errors.block["tail_ranging"][k, j]
                rng_m, bearing = sensors.range_bearing(self.poses[i], xy[j], noise)
                if rng_m <= spec.ranging_max_m:
                    row = np.array([self.vehicles[j].vehicle_id, rng_m, bearing, *cov])
                    self._emit(out.rows[v.vehicle_id], v, Topic.RANGING, t_us, row)
