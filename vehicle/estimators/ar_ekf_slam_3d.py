"""``ar-ekf-slam-3d``: the AR-EKF-SLAM paper's own system as a vehicle's estimator: the 6 + 3n EKF of
vehicle.estimators.ar_slam3d (position and velocity with the constant-velocity model, each landmark's
3-D position, the adaptive range in 3-D distance) fed by a UAV's 3-D camera (bus.sensors.camera3d)
and its GNSS receiver. Pure: no bus, no clock; the vehicle process runs it as it runs a ``Filter``
(the same interface: ``handle``, ``cycle``, ``snapshot`` and ``restore`` for the fusion horizon,
``estimate``, ``health``).

Between frames, the gyro's yaw rate turns the heading and the horizontal velocity
(vehicle.estimators.gyro_turn; a UAV that flies nose first, as the world's do: at every prediction
step the turn since the last, half before and half after); without a gyro the velocity turns with
the frames' headings. Per camera frame (its tracked points, which share the frame's stamp, heading
and displacement): the state is predicted to the frame and the frame's heading resets the heading;
the points the frame and the frame ``baseline_s`` earlier both track are triangulated
(vehicle.vision.tracked_frames: the rotation the paper takes from visual odometry comes from the
attitude sensor's headings, the scale it takes from an inertial unit from the inertial
displacement). The errors a frame's points share (the two headings', the displacement's) are states
of the back end while the frame's points are fused (ArSlam3d.frame's ``common``), so that they count
once. The points are then associated with the map by nearest neighbour behind the chi-square gate,
fused, entered and retired as the back end does. Track ids only pair a point's pixels across frames
(what a tracker gives); the map is associated on geometry.

The motion model's white acceleration (``ACCEL_PSD``, m^2/s^3 per axis) covers changes of speed
and climbing and descending with the relief; turns are the gyro's. Its horizontal part was chosen on
flights never scored (seeds 101-106 of scenarios/uav-3d.toml, 18 flights): of 0.05, 0.2, 0.5 and
2.0, the one whose pooled 2-dof ANEES of the published position is nearest 2 (2.33, 2.13, 2.07 and
12.64; with 2.0 the position's sigma outgrows the spacing of the points after a few seconds without
fusing, every pairing is ambiguous, and two flights were lost; docs/decisions/ar-slam3d-processes.md).
The altitude is not observed absolutely (no altimeter, and GNSS fixes are horizontal): it is the
height above the take-off point, 0 at the start (``ALTITUDE_SIGMA_M``, small: the camera measures
only differences of height, and an origin uncertain by metres would leave the vehicle and its map
with variances hundreds of times those differences'), and the map's heights follow it. The published
pose is [x, y, heading]: the position's horizontal rows, and the last frame's heading turned by the
gyro since, its variance grown by the gyro's noise and unknown bias (the IMU's datasheet); with it
the altitude (ODOMETRY's z, above the launch point, with its variance and covariances), which the
ground station scores.

Lost and found again: when ``LOST_AFTER_FIXES`` GNSS fixes in a row fail the gate (the map carried
the vehicle off while GNSS was jammed, and the filter is sure of a wrong place), the map is dropped,
the horizontal position is put at the last fix with its covariance and the velocity's variance is
widened; a notice says so and ``resets`` counts it.
"""

from __future__ import annotations

import copy
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from bus.config import ArSlamConfig, SensorSpec, VehicleProcessConfig
from bus.estimate import Altitude, Health, PoseEstimate
from bus.sensors.camera3d import Camera3dSpec, TrackedPoint
from bus.sensors.camera3d import look as camera_rotation
from bus.statistics import gate_threshold
from vehicle.estimators.ar_slam3d import ArSlam3d
from vehicle.estimators.gyro_turn import Gyro
from vehicle.estimators.state import SEVERITY_WARNING, EstimatorCounters, Notice, Notices
from vehicle.models import slam3d
from vehicle.vision.tracked_frames import NO_POINTS, Frame, frame_points

ACCEL_PSD = np.array([0.5, 0.5, 0.05])  # m^2/s^3: x, y, up
ALTITUDE_SIGMA_M, SPEED_SIGMA_MPS = 0.05, 5.0
GNSS_GATE_PROBABILITY = 0.9995
LOST_AFTER_FIXES = 3  # GNSS fixes in a row failing the gate


@dataclass
class Slam3dState:
    """Everything a fusion-horizon replay restores: the back end (None before the prior), the time it
    stands at, the recent frames, the frame being received, the counters, the heading and its
    variance, the gyro's account, the GNSS test ratio, the GNSS fixes in a row that failed the gate."""

    slam: ArSlam3d | None = None
    time_us: int = 0
    frames: deque = field(default_factory=deque)
    receiving: Frame | None = None
    counters: EstimatorCounters = field(default_factory=EstimatorCounters)
    heading_rad: float = 0.0
    heading_var: float = 0.0
    gyro: Gyro = field(default_factory=lambda: Gyro())
    gnss_ratio: float = 0.0
    fixes_failed: int = 0


class ArEkfSlam3d:
    """The estimator (module docstring) of vehicle ``vehicle_id``."""

    name = "ar-ekf-slam-3d"

    def __init__(
        self,
        vehicle_id: int,
        camera: Camera3dSpec,
        ar: ArSlamConfig,
        association: str = "nn",
        imu: SensorSpec | None = None,
    ) -> None:
        self.vehicle_id, self.camera = vehicle_id, camera
        self._imu = imu if imu is not None else SensorSpec()
        self._ar, self._association = ar, association
        self._pitch = np.deg2rad(camera.pitch_deg)
        self._gnss_gate = gate_threshold(2, GNSS_GATE_PROBABILITY)
        self.state = Slam3dState()
        self.notices = Notices()

    # -- what the node asks ---------------------------------------------------------------------

    @property
    def initialized(self) -> bool:
        return self.state.slam is not None

    @property
    def resets(self) -> int:
        return self.state.counters.resets

    @property
    def counters(self) -> EstimatorCounters:
        return self.state.counters

    def snapshot(self) -> Slam3dState:
        return copy.deepcopy(self.state)

    def restore(self, snapshot: Slam3dState) -> None:
        self.state = copy.deepcopy(snapshot)

    def accused(self) -> tuple[int, ...]:
        return ()

    def add_part(self, part: Any) -> None:
        """A part of a sensor added by the recipe: this estimator fuses its own camera and GNSS only."""

    def landmark_map(self) -> tuple[np.ndarray, ...] | None:
        """The landmarks in the state: positions (m, 2), their covariances (m, 2, 2), heights (m,) up
        from the launch point, and the full covariances (m, 3, 3) (bus.landmark_map)."""
        slam = self.state.slam
        if slam is None:
            return None
        n = slam3d.landmarks(slam.x)
        rows = slam3d.HEAD + slam3d.POINT * np.arange(n)
        blocks = rows[:, None] + np.arange(3)  # (n, 3) each landmark's rows
        points = slam.x[blocks] if n else np.zeros((0, 3))
        cov3 = slam.P[blocks[:, :, None], blocks[:, None, :]] if n else np.zeros((0, 3, 3))
        return points[:, :2], cov3[:, :2, :2], points[:, 2], cov3

    def estimate(self, t_us: int) -> PoseEstimate:
        s = self.state
        slam = s.slam
        cov = np.zeros((3, 3))
        cov[:2, :2] = slam.P[:2, :2]
        cov[2, 2] = s.heading_var
        speed = float(np.hypot(slam.x[3], slam.x[4]))
        return PoseEstimate(
            vehicle_id=self.vehicle_id,
            stamp_us=max(t_us, s.time_us),
            pose=np.array([slam.x[0], slam.x[1], s.heading_rad]),
            pose_cov=cov,
            speed_mps=speed,
            speed_var=float(0.5 * (slam.P[3, 3] + slam.P[4, 4])),
            altitude=Altitude(float(slam.x[2]), float(slam.P[2, 2]), (float(slam.P[0, 2]), float(slam.P[1, 2]))),
        )

    def health(self, t_us: int) -> Health:
        slam = self.state.slam
        sigma = float(np.sqrt(0.5 * (slam.P[0, 0] + slam.P[1, 1]))) if slam is not None else 1e3
        return Health(self.vehicle_id, t_us, True, self.state.gnss_ratio, sigma)

    # -- measurements -------------------------------------------------------------------------

    def handle(self, msg: Any) -> None:
        s = self.state
        kind = type(msg)
        if kind is m.PosePrior:
            self._initialise(msg)
            return
        if s.slam is None:
            return
        if kind is TrackedPoint:
            self._take_point(msg)
        elif kind is m.ImuSample:
            self._gyro(msg.stamp_us, float(msg.gyro_radps[2]))
        elif kind is m.GnssFix:
            self._finish_frame(msg.stamp_us)
            if msg.stamp_us < s.time_us:
                s.counters.stale += 1
                return
            self._predict_to(msg.stamp_us)
            result = s.slam.position_fix(np.asarray(msg.position_m), np.asarray(msg.covariance_m2), self._gnss_gate)
            s.gnss_ratio = result.test_ratio
            s.counters.gnss_accepted += int(result.accepted)
            s.counters.gnss_rejected += int(not result.accepted)
            s.fixes_failed = 0 if result.accepted else s.fixes_failed + 1
            if s.fixes_failed >= LOST_AFTER_FIXES:
                self._relocalize(msg)

    def handle_row(self, topic: str, stamp_us: int, row: list[float], message) -> None:
        """An IMU row's yaw rate turns the heading and the velocity (``_gyro``); wheel rows are not used."""
        if topic == "imu" and self.state.slam is not None:
            self._gyro(stamp_us, float(row[2]))

    def cycle(self, t_us: int) -> None:
        s = self.state
        if s.slam is None:
            return
        self._finish_frame(t_us)
        self._predict_to(t_us)
        s.counters.landmarks = slam3d.landmarks(s.slam.x)

    # -- the steps ----------------------------------------------------------------------------

    def _initialise(self, prior: m.PosePrior) -> None:
        """Start at the prior's horizontal position (its covariance), altitude 0 (ALTITUDE_SIGMA_M), at
        rest (SPEED_SIGMA_MPS per horizontal axis)."""
        x0 = np.zeros(slam3d.HEAD)
        x0[:2] = prior.pose[:2]
        P0 = np.diag([0.0, 0.0, ALTITUDE_SIGMA_M**2] + [SPEED_SIGMA_MPS**2, SPEED_SIGMA_MPS**2, 1.0])
        P0[:2, :2] = prior.covariance[:2, :2]
        self.state = Slam3dState(
            slam=ArSlam3d(
                x0,
                P0,
                spec=self._ar,
                association=self._association,
                seed=self.vehicle_id,
                unambiguous=True,
            ),
            time_us=prior.stamp_us,
            heading_rad=float(prior.pose[2]),
            heading_var=float(prior.covariance[2, 2]),
        )

    def _relocalize(self, fix: m.GnssFix) -> None:
        """Lost (module docstring): the map dropped, the position put at the fix, a notice."""
        s = self.state
        s.slam.relocalize(np.asarray(fix.position_m), np.asarray(fix.covariance_m2), SPEED_SIGMA_MPS**2)
        s.counters.resets += 1
        text = f"lost track: {s.fixes_failed} GNSS fixes in a row failed the gate; map dropped, position from GNSS"
        s.fixes_failed = 0
        self.notices.say(Notice(fix.stamp_us, SEVERITY_WARNING, text))

    def _predict_to(self, t_us: int) -> None:
        """The constant-velocity step to ``t_us``, the velocity turned by the gyro's turn since the last
        step, half before and half after."""
        s = self.state
        if t_us > s.time_us:
            dt = (t_us - s.time_us) * 1e-6
            turn_rad, turn_var = s.gyro.take_turn()
            s.slam.turn_velocity(0.5 * turn_rad, 0.5 * turn_var)
            s.slam.predict(dt, ACCEL_PSD * dt)
            s.slam.turn_velocity(0.5 * turn_rad, 0.5 * turn_var)
            s.time_us = t_us

    def _gyro(self, stamp_us: int, rate_radps: float) -> None:
        """One gyro sample (vehicle.estimators.gyro_turn), unless the state is already past it."""
        s = self.state
        if stamp_us >= s.time_us:
            s.heading_rad, s.heading_var = s.gyro.sample(stamp_us, rate_radps, s.heading_rad, s.heading_var, self._imu)

    def _take_point(self, point: TrackedPoint) -> None:
        """One tracked point: the frame it belongs to is received row by row (one stamp)."""
        s = self.state
        if s.receiving is not None and point.stamp_us != s.receiving.stamp_us:
            self._finish_frame(point.stamp_us - 1)
        if s.receiving is None:
            if point.stamp_us < s.time_us:
                s.counters.stale += 1
                return
            s.receiving = Frame(point.stamp_us, point.heading_rad, np.array(point.baseline_m), point.baseline_s)
        s.receiving.pixels[point.track_id] = point.pixel

    def _finish_frame(self, until_us: int) -> None:
        """Fuse the frame being received once nothing more of it can come (a later stamp, or a cycle)."""
        s = self.state
        frame = s.receiving
        if frame is None or frame.stamp_us > until_us:
            return
        s.receiving = None
        if s.gyro.last_us < 0:  # no gyro: the velocity turns with the frames' headings
            s.gyro.turn_rad = float(wrap_angle(frame.heading_rad - s.heading_rad))
            s.gyro.turn_var = 2.0 * self.camera.heading_sigma_rad**2
        self._predict_to(frame.stamp_us)
        s.heading_rad, s.heading_var = frame.heading_rad, self.camera.heading_sigma_rad**2
        s.gyro.since_frame_s = 0.0
        earlier = next((f for f in s.frames if f.stamp_us == frame.earlier_us), None)
        z, R_z, common, _ = frame_points(earlier, frame, self.camera) if earlier is not None else NO_POINTS
        s.slam.frame(z, R_z, camera_rotation(frame.heading_rad, self._pitch), common=common)
        s.counters.frames_used += 1
        s.counters.landmarks_updated = len(z)
        s.frames.append(frame)
        keep_us = round(frame.span_s * 1e6) if frame.span_s else round(self.camera.baseline_s * 1e6)
        while s.frames and s.frames[0].stamp_us < frame.stamp_us - keep_us:
            s.frames.popleft()


def from_config(config: VehicleProcessConfig, vehicle_id: int, *, reject=None) -> ArEkfSlam3d:
    association = config.vehicle.association
    association = "nn" if association == "descriptor" else association  # a tracked point has no descriptor
    return ArEkfSlam3d(vehicle_id, config.sensors.camera3d, config.vehicle.ar, association, imu=config.sensors)
