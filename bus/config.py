"""The swarm configuration: one pydantic model tree for the world and the ground station (written
to the run directory as ``config.json``), and the much smaller :class:`VehicleProcessConfig` that is
all a vehicle process is given (``vehicle.json``): its sensors' datasheet, its estimator settings and
the link faults of the plan; never the world seed, the trajectories or anything else that determines
truth.

Units are in the field names. Bus endpoints can be overridden from the environment
(``SWARMLOC_ZENOH_MODE``, ``SWARMLOC_ZENOH_CONNECT``, ``SWARMLOC_ZENOH_LISTEN``, ``SWARMLOC_PREFIX``,
``SWARMLOC_ZENOH_CONNECT_TIMEOUT_S``; lists are comma separated), as containers need.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from bus.errors import ConfigError
from bus.estimators import ESTIMATORS, EstimatorName
from bus.faults import BEHAVIOUR_KINDS, LINK_KINDS, Fault, check_fault, named
from bus.replay_config import ReplayConfig


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class BusConfig(_Strict):
    prefix: str = Field("swarm", pattern=r"^[A-Za-z0-9_\-]+(/[A-Za-z0-9_\-]+)*$")
    mode: Literal["peer", "client", "router"] = "client"
    connect: tuple[str, ...] = ("tcp/127.0.0.1:7447",)
    listen: tuple[str, ...] = ()
    connect_timeout_s: float = Field(180.0, gt=0, le=86400, description="a client waits this long for its router")

    def with_env(self, env: dict[str, str] | None = None) -> BusConfig:
        """This config with ``SWARMLOC_*`` environment overrides applied."""
        env = os.environ if env is None else env
        updates: dict[str, object] = {}
        if env.get("SWARMLOC_ZENOH_MODE"):
            updates["mode"] = env["SWARMLOC_ZENOH_MODE"]
        for name in ("connect", "listen"):
            value = env.get(f"SWARMLOC_ZENOH_{name.upper()}")
            if value is not None:
                updates[name] = tuple(e.strip() for e in value.split(",") if e.strip())
        if env.get("SWARMLOC_PREFIX"):
            updates["prefix"] = env["SWARMLOC_PREFIX"]
        if env.get("SWARMLOC_ZENOH_CONNECT_TIMEOUT_S"):
            updates["connect_timeout_s"] = env["SWARMLOC_ZENOH_CONNECT_TIMEOUT_S"]
        return _validated(BusConfig, {**self.model_dump(), **updates})


class ClockConfig(_Strict):
    mode: Literal["lockstep", "realtime"] = "lockstep"
    speed: float = Field(1.0, gt=0, le=1000, description="realtime: sim seconds per wall second")
    tick_s: float | None = Field(
        None,
        gt=0,
        le=1.0,
        description="sim time per clock tick (lockstep barrier): default 0.02 in realtime; in lockstep 1, or 0.5 "
        "with cameras, a live view, kill faults or a truth batch too large for 1 s",
    )
    duration_s: float = Field(60.0, gt=0, le=86400)
    ack_timeout_s: float = Field(10.0, gt=0, description="lockstep: wall time before a silent vehicle is dead")
    start_timeout_s: float = Field(60.0, gt=0, description="wall time to wait for every process to join")
    gone_timeout_s: float = Field(
        30.0,
        gt=0,
        description="wall time the world and the ground station wait for "
        "each other after one disappears, before ending the run",
    )
    gs_lag_ticks: int = Field(
        1,
        ge=1,
        le=10_000,
        description="lockstep: how many ticks the ground station may lag "
        "(what a ground-station crash can lose: up to 1 s of scoring at the default tick)",
    )
    background_niceness: int = Field(
        19,
        ge=0,
        le=19,
        description="lockstep: the niceness the world and the ground station run at, so that the vehicles' "
        "cycles, the barrier's critical path, get the cores first (0: the default priority)",
    )

    @model_validator(mode="after")
    def _default_tick(self) -> ClockConfig:
        """Realtime's default tick; lockstep's depends on the rest of the run (SwarmConfig)."""
        if self.tick_s is None and self.mode == "realtime":
            object.__setattr__(self, "tick_s", 0.02)
        return self


class SensorSpec(_Strict):
    """Rates and noise of the simulated sensors (also the vehicles' datasheet noise model)."""

    imu_rate_hz: float = Field(100.0, gt=0, le=1000)
    gyro_sigma_radps: float = Field(0.01, ge=0)
    gyro_bias_sigma_radps: float = Field(0.005, ge=0, description="initial gyro bias spread")
    gyro_bias_walk_radps_rtsec: float = Field(0.0005, ge=0)
    accel_sigma_mps2: float = Field(0.05, ge=0)
    odom_rate_hz: float = Field(50.0, gt=0, le=1000)
    odom_speed_sigma_mps: float = Field(0.05, ge=0)
    odom_yaw_rate_sigma_radps: float = Field(0.02, ge=0)
    odom_turn_sigma_rad: float = Field(
        0.0,
        ge=0,
        le=1.0,
        description="odometry heading error per square root of "
        "the angle turned (rad/sqrt(rad)): wheels that slip in turns. Replays only "
        "(calibrated); the simulated world makes no such error",
    )
    odom_travel_sigma_m: float = Field(
        0.0,
        ge=0,
        le=1.0,
        description="odometry along-track error per square root of "
        "the distance travelled (m/sqrt(m)). Replays only, as above",
    )
    gnss_rate_hz: float = Field(5.0, gt=0, le=100)
    gnss_sigma_m: float = Field(1.5, gt=0)
    gnss_correlated_sigma_m: float = Field(
        0.0,
        ge=0,
        description="of gnss_sigma_m, the part that wanders slowly "
        "(per axis; 0: white). ekf and ukf then estimate it as two "
        "Gauss-Markov states; ekf-slam treats all of it as white",
    )
    gnss_correlation_s: float = Field(60.0, gt=0, le=1e5, description="correlation time of that part")
    truth_rate_hz: float = Field(50.0, gt=0, le=1000)
    ranging_rate_hz: float = Field(5.0, gt=0, le=100, description="vehicle-to-vehicle radio ranging")
    ranging_max_m: float = Field(150.0, ge=0, description="ranging reaches vehicles this close (0: no ranging)")
    ranging_max_peers: int = Field(4, ge=0, le=249, description="the radio ranges at most this many peers, the nearest")
    range_sigma_m: float = Field(0.3, gt=0)
    bearing_sigma_rad: float = Field(0.02, gt=0)
    range_correlated_sigma_per_m: float = Field(
        0.0,
        ge=0,
        le=0.5,
        description="of a camera's landmark range "
        "error, the part that persists in time, per metre of range "
        "(0.03: 3 %; 0: white). known-map estimates it per landmark",
    )
    range_correlation_s: float = Field(5.0, gt=0, le=1e4, description="correlation time of that part")
    bearing_correlated_fraction: float = Field(
        0.0,
        ge=0,
        le=0.95,
        description="of a camera's landmark bearing "
        "error variance, the part that persists in time (0: white); "
        "known-map and slam estimate it per landmark",
    )
    bearing_correlation_s: float = Field(5.0, gt=0, le=1e4, description="correlation time of that part")
    range_scale_prior_sigma: float = Field(
        0.0,
        ge=0,
        le=0.5,
        description="how far a camera's range scale may "
        "be off (0.05: 5 %, every landmark read that much long or short); "
        "known-map then estimates it (0: taken as exact)",
    )
    odom_scale_prior_sigma: float = Field(
        0.0,
        ge=0,
        le=0.5,
        description="how far the wheel odometry's speed "
        "and yaw-rate scales may be off (0.1: 10 %); known-map then "
        "estimates both (0: taken as exact)",
    )
    prior_sigma_m: float = Field(0.5, gt=0, description="launch-pad survey of the start position")
    unmodelled_sigma_m: float = Field(
        0.0,
        ge=0,
        le=10,
        description="how far, per axis, a replayed robot may lie from where its filter puts it beyond the "
        "filter's own covariance (what no sighting sees, what a calibration cannot know): added to the "
        "published position covariance, not to the filter's own (measured out of sample by the "
        "calibration, launch.unmodelled; the simulated world has no such error)",
    )
    prior_heading_sigma_rad: float = Field(0.05, gt=0)
    camera_rate_hz: float = Field(0.0, ge=0, le=100, description="down-looking camera frames (0: no camera)")
    camera_size_px: int = Field(80, ge=16, le=1024, description="square frame side (the paper's 80 px)")
    camera_noise_grey: float = Field(2.0, ge=0, le=100, description="pixel noise, grey levels (world)")
    keypoint_sigma_px: float = Field(0.7, gt=0, le=20, description="keypoint position noise the filter assumes")

    @model_validator(mode="after")
    def _correlated_part_is_a_part(self) -> SensorSpec:
        if self.gnss_correlated_sigma_m >= self.gnss_sigma_m:
            raise ValueError(
                f"gnss_correlated_sigma_m ({self.gnss_correlated_sigma_m} m) must be below "
                f"gnss_sigma_m ({self.gnss_sigma_m} m): it is a part of the total"
            )
        return self


class SensorTruth(_Strict):
    """How the world really is next to the datasheet (``sensors``), which is all the vehicles are
    told. The defaults are the idealized world (the filters' own models); ``HONEST_WORLD`` is a
    world richer than any filter: finer truth steps with inputs that vary inside a step, wheel scale
    error and slip, a time-correlated GNSS error with outliers, heavy-tailed noise."""

    gnss_sigma_factor: float = Field(1.0, gt=0, le=100, description="true GNSS white noise / datasheet")
    range_sigma_factor: float = Field(1.0, gt=0, le=100, description="true ranging noise / datasheet")
    substeps: int = Field(1, ge=1, le=100, description="truth integrated at the IMU period / substeps")
    wobble_speed_mps: float = Field(
        0.0,
        ge=0,
        le=10,
        description="RMS of a smooth speed variation (0.05-1.5 Hz) "
        "on top of the trajectory's law, varying inside a step",
    )
    wobble_yaw_rate_radps: float = Field(0.0, ge=0, le=2, description="RMS of the same for the yaw rate")
    odom_scale_sigma: float = Field(
        0.0, ge=0, le=0.5, description="spread of each vehicle's constant wheel scale error (0.01: 1 %)"
    )
    odom_slip_rate_hz: float = Field(0.0, ge=0, le=10, description="wheel slip episodes per second")
    odom_slip_s: float = Field(0.5, gt=0, le=60, description="length of a slip episode")
    odom_slip_fraction: float = Field(0.2, ge=-1, le=5, description="odometry reads speed x (1 + this) while slipping")
    gnss_walk_sigma_m: float = Field(
        0.0,
        ge=0,
        le=100,
        description="time-correlated GNSS error per axis: stationary sigma of a first-order Gauss-Markov process",
    )
    gnss_walk_tau_s: float = Field(60.0, gt=0, le=1e5, description="its correlation time")
    gnss_outlier_probability: float = Field(0.0, ge=0, le=1, description="share of fixes that are outliers")
    gnss_outlier_m: float = Field(20.0, ge=0, le=1e4, description="typical outlier size (0.5-1.5 x this)")
    heavy_tail_dof: float = Field(
        0.0,
        ge=0,
        le=1000,
        description="0: Gaussian white noise; > 2: Student-t "
        "with this many degrees of freedom and the same sigma (odometry, GNSS, ranging)",
    )

    @model_validator(mode="after")
    def _tail_has_a_variance(self) -> SensorTruth:
        if 0 < self.heavy_tail_dof <= 2:
            raise ValueError("heavy_tail_dof must be 0 (Gaussian) or above 2 (a Student-t with a variance)")
        return self


# A world richer than the filters (issue 13; `swarm experiment cooperative`, the staged tests): the
# datasheet's GNSS sigma (1.5 m) is split into 1.2 m white and 0.9 m Gauss-Markov (60 s), so the total
# matches the datasheet but half of it no longer averages out.
HONEST_WORLD = {
    "gnss_sigma_factor": 0.8,
    "substeps": 5,
    "wobble_speed_mps": 0.2,
    "wobble_yaw_rate_radps": 0.03,
    "odom_scale_sigma": 0.005,
    "odom_slip_rate_hz": 0.02,
    "gnss_walk_sigma_m": 0.9,
    "gnss_walk_tau_s": 60.0,
    "gnss_outlier_probability": 0.002,
    "heavy_tail_dof": 5.0,
}
# What the filters are told in that world (the datasheet, rounded: the world's Gauss-Markov part is
# 0.9 m over 60 s, the datasheet says 1 m and a minute).
HONEST_DATASHEET = {"gnss_correlated_sigma_m": 1.0, "gnss_correlation_s": 60.0}


class WorldConfig(_Strict):
    vehicles: int = Field(5, ge=1, le=250)
    seed: int = Field(0, ge=0)
    trajectories: tuple[Literal["circle", "figure8", "waypoints"], ...] = ("circle", "figure8", "waypoints")
    speed_mps: float = Field(4.0, gt=0, le=100)
    radius_m: float = Field(20.0, gt=0)
    altitude_m: float = Field(30.0, ge=0)
    spacing_m: float = Field(60.0, gt=0, description="distance between neighbouring start pads")
    terrain: str = Field("", description="orthophoto (PNG/JPEG) the cameras see; empty: a procedural terrain")
    terrain_metres_per_pixel: float = Field(0.1, gt=0, le=100)
    terrain_size_px: int | None = Field(
        None,
        ge=256,
        le=8192,
        description="side of the procedural terrain "
        "(default: large enough for every start pad and trajectory, at least 2048)",
    )
    terrain_period_px: int = Field(
        0,
        ge=0,
        le=512,
        description="procedural terrain: 0 varied ground; above 0 one tile of this side repeated "
        "(repetitive texture: every keypoint has look-alikes a period away)",
    )
    sensor_truth: SensorTruth = SensorTruth()


class ArSlamConfig(_Strict):
    """``ar-ekf-slam``'s adaptive observation range (the AR-EKF-SLAM paper's values as defaults)."""

    r0_m: float = Field(25.0, gt=0, le=10_000, description="the range R a flight starts with (m)")
    r_max_m: float = Field(35.0, gt=0, le=10_000, description="R grows no further than this (m)")
    n_min: int = Field(8, ge=1, le=100_000, description="fewer landmarks in the local map: R grows")
    n_max: int = Field(50, ge=2, le=100_000, description="more landmarks in the local map: R shrinks")
    dr_m: float = Field(0.1, gt=0, le=1_000, description="how much R changes per camera frame (m)")
    reentry: Literal["reinit", "ci", "naive"] = Field(
        "reinit",
        description="a retired landmark seen again: reinit (initialised as new), ci (and its old marginal "
        "fused by Covariance Intersection) or naive (its old marginal put back uncorrelated: over-confident)",
    )

    @model_validator(mode="after")
    def _a_range_that_can_settle(self) -> ArSlamConfig:
        if self.r0_m > self.r_max_m:
            raise ValueError(f"r0_m {self.r0_m:g} is above r_max_m {self.r_max_m:g}")
        if self.n_min >= self.n_max:
            raise ValueError(f"n_min {self.n_min} must be below n_max {self.n_max}")
        if self.dr_m >= self.r_max_m:
            raise ValueError(f"dr_m {self.dr_m:g} must be below r_max_m {self.r_max_m:g}")
        return self


class VehicleConfig(_Strict):
    estimator: EstimatorName = Field(
        "ekf",
        description="the estimator every vehicle runs: "
        + "; ".join(f"{name}: {entry.summary}" for name, entry in ESTIMATORS.items()),
    )
    landmarks: tuple[tuple[int, float, float], ...] = Field(
        (), max_length=10_000, description="known-map: the surveyed landmarks, (id, x m, y m)"
    )
    features: Literal["sift", "orb"] = Field("sift", description="ekf-slam, ar-ekf-slam: keypoint detector")
    ar: ArSlamConfig = Field(default_factory=ArSlamConfig, description="ar-ekf-slam: the adaptive range")
    association: Literal["descriptor", "nn", "jcbb", "aco"] = Field(
        "descriptor",
        description="ekf-slam, ar-ekf-slam: which keypoint is which landmark: descriptor match with a rigid "
        "consensus, or among each landmark's descriptor shortlist Mahalanobis nearest neighbour (nn), joint "
        "compatibility branch and bound (jcbb) or the ant colony (aco)",
    )
    odometry: Literal["wheel", "visual"] = Field(
        "wheel",
        description="where every vehicle's speed comes from: its wheels, or visual odometry from consecutive "
        "camera frames (a vehicle without wheels; needs sensors.camera_rate_hz)",
    )
    visual_odometry_vehicles: tuple[int, ...] = Field(
        (), max_length=1000, description="these vehicles use visual odometry whatever `odometry` says"
    )
    loop_rate_hz: float = Field(50.0, gt=0, le=1000)
    gate_probability: float = Field(0.9995, gt=0.5, lt=1.0, description="chi-square gate for GNSS")
    heartbeat_period_s: float = Field(1.0, gt=0)
    status_period_s: float = Field(1.0, gt=0)
    fusion_horizon_s: float = Field(
        0.5, ge=0, le=10, description="late measurements up to this old are still fused in order"
    )
    cooperative: bool = Field(True, description="fuse ranging to neighbours with their broadcast estimates (CI)")
    cooperative_fusion: Literal["split-ci", "ci", "paper", "naive"] = Field(
        "split-ci",
        description="split-ci: Covariance Intersection scaling only the neighbour's share, the radio's "
        "own noise kept whole (consistent whatever the correlation); ci: plain CI; paper: CI of the position "
        "the fix implies (paper eq. 4.10); naive: a plain Kalman update that treats the neighbour's estimate as "
        "independent (double counts)",
    )
    ci_weight: Literal["optimal", "closed-form"] = Field(
        "optimal",
        description="CI weight: optimal (maximum "
        "pose information, w = 1 skips the fix) or closed-form "
        "(plain CI's best weight in closed form)",
    )
    adaptive_noise: bool = Field(
        False,
        description="IAE: estimate the GNSS and ranging noise covariances from the "
        "innovations of the last adaptive_window fixes instead of trusting the datasheet (never below it: "
        "a CI-fused covariance is a bound, so a quieter-looking sensor is its slack)",
    )
    adaptive_window: int = Field(40, ge=5, le=10_000, description="IAE window, fixes per sensor")
    neighbour_monitor: bool = Field(
        True,
        description="judge each neighbour's fixes for consistency and stop fusing a neighbour that lies "
        "(vehicle.neighbours; docs: liars)",
    )
    max_compromised: int = Field(
        1,
        ge=0,
        le=250,
        description="f: how many vehicles may be compromised (their own keys, any lie or accusation); a "
        "neighbour a vehicle cannot judge itself is distrusted on the word of more than f (docs: security)",
    )
    trust_rule: Literal["evidence", "quorum-only"] = Field(
        "evidence",
        description="evidence: the others' word never outweighs a vehicle's own evidence and accusers are "
        "judged; quorum-only: the rule before, a quorum's word decides (a control; docs: security)",
    )

    def visual_odometry(self, vehicle_id: int) -> bool:
        """Does this vehicle take its speed from visual odometry?"""
        return self.odometry == "visual" or vehicle_id in self.visual_odometry_vehicles

    v2v_latency_s: float = Field(0.1, ge=0, le=5, description="ranging waits this long for the neighbour's estimate")
    mavlink_rate_hz: float = Field(
        10.0,
        gt=0,
        le=1000,
        description="ODOMETRY to the ground station (<= loop rate; "
        "a telemetry rate: the ground station scores every estimate it receives)",
    )
    realtime_allowance_s: float = Field(
        0.005, ge=0, le=1, description="realtime: a cycle waits this long past its deadline for the tick's sensor batch"
    )
    realtime_priority: int = Field(
        10,
        ge=0,
        le=99,
        description="realtime: the estimator loop runs under SCHED_FIFO at this priority when the kernel allows "
        "it (root, CAP_SYS_NICE or `ulimit -r`), else under the fair scheduler; 0: always the fair scheduler "
        "(vehicle.scheduling)",
    )
    world_timeout_s: float = Field(60.0, gt=0, description="a vehicle whose world is gone this long gives up")


class ViewConfig(_Strict):
    """What the ground station shows and records for Foxglove or Lichtblick (groundstation.recording)."""

    record: bool = Field(True, description="write run.mcap in the run directory (scene, poses, metrics, events)")
    live: bool = Field(False, description="serve a Foxglove WebSocket live view while the swarm runs")
    live_host: str = Field("127.0.0.1", min_length=1, max_length=255, description="the live view's address")
    live_port: int = Field(8765, ge=1, le=65535, description="the live view's port")
    live_backlog: int = Field(
        1024, ge=1, le=1_000_000, description="messages queued per live viewer; a slow viewer loses the oldest"
    )
    live_speed: float | None = Field(
        None,
        gt=0,
        le=10_000,
        description="lockstep with the live view on: run at most this many times real time, so that a viewer "
        "can watch (the ground station holds its tick acknowledgements; None: as fast as the swarm goes)",
    )


class SwarmConfig(_Strict):
    name: str = Field("run", pattern=r"^[A-Za-z0-9_.\-]+$")
    bus: BusConfig = BusConfig()
    clock: ClockConfig = ClockConfig()
    world: WorldConfig = WorldConfig()
    sensors: SensorSpec = SensorSpec()
    vehicle: VehicleConfig = VehicleConfig()
    view: ViewConfig = ViewConfig()
    faults: tuple[Fault, ...] = Field((), description="fault timeline (physical, link and kill faults)")
    replay: ReplayConfig | None = Field(
        None,
        description="replay a recorded data set instead of simulating "
        "(world.vehicles is then the number of robots replayed)",
    )
    fault_seed: int = Field(
        1,
        ge=0,
        le=2**63 - 1,
        description="seed of link-fault decisions; independent of world.seed, which vehicles never see",
    )

    @model_validator(mode="after")
    def _default_lockstep_tick(self) -> SwarmConfig:
        """Lockstep's tick when none is given: 1 s, a barrier round trip per 50 loop cycles (0.5 s took
        14 % more CPU for the same run, and the result is the same whatever the tick), or 0.5 s where a
        longer one would cost something: camera frames (a tick's batch of frames grows with it), a
        live view (paced a tick at a time), kill faults (a kill lands at a tick's end) and a truth batch
        that 1 s would make larger than the ground station takes (many vehicles at a high truth rate)."""
        from bus.feed import MAX_TRUTH_BYTES, truth_batch_bytes

        if self.clock.tick_s is None:
            short = self.sensors.camera_rate_hz or self.view.live or any(f.kind == "kill" for f in self.faults)
            short = short or truth_batch_bytes(self.sensors.truth_rate_hz, 1.0, self.world.vehicles) > MAX_TRUTH_BYTES
            object.__setattr__(self, "clock", self.clock.model_copy(update={"tick_s": 0.5 if short else 1.0}))
        size = truth_batch_bytes(self.sensors.truth_rate_hz, self.clock.tick_s, self.world.vehicles)
        if size > MAX_TRUTH_BYTES:
            raise ValueError(
                f"a tick's truth batch ({self.world.vehicles} vehicles at {self.sensors.truth_rate_hz:g} Hz for "
                f"{self.clock.tick_s:g} s) would be about {size >> 10} kB, more than the ground station takes "
                f"({MAX_TRUTH_BYTES >> 10} kB): lower sensors.truth_rate_hz or clock.tick_s"
            )
        return self

    @model_validator(mode="after")
    def _faults_are_named_and_valid(self) -> SwarmConfig:
        faults = named(list(self.faults))
        names = [f.name for f in faults]
        if len(set(names)) != len(names):
            raise ValueError(f"fault names must be unique, got {names}")
        for f in faults:
            check_fault(f, self.world.vehicles)
        object.__setattr__(self, "faults", tuple(faults))
        return self

    @model_validator(mode="after")
    def _rates_fit_the_world_step(self) -> SwarmConfig:
        step_us = round(1e6 / self.sensors.imu_rate_hz)
        for label, rate in [
            ("odom", self.sensors.odom_rate_hz),
            ("gnss", self.sensors.gnss_rate_hz),
            ("ranging", self.sensors.ranging_rate_hz),
            *([("camera", self.sensors.camera_rate_hz)] if self.sensors.camera_rate_hz else []),
            ("truth", self.sensors.truth_rate_hz),
            ("tick", 1.0 / self.clock.tick_s),
        ]:
            if round(1e6 / rate) % step_us:
                raise ValueError(f"{label} period must be a multiple of the IMU period ({step_us} us)")
        return self

    @model_validator(mode="after")
    def _cycles_fit_the_tick(self) -> SwarmConfig:
        period_us = round(1e6 / self.vehicle.loop_rate_hz)
        if round(self.clock.tick_s * 1e6) % period_us or round(1e6 / self.vehicle.mavlink_rate_hz) % period_us:
            raise ValueError(f"the tick and the MAVLink period must be multiples of the loop period ({period_us} us)")
        return self

    @model_validator(mode="after")
    def _slam_has_a_camera(self) -> SwarmConfig:
        slam = self.vehicle.estimator in ("ekf-slam", "ar-ekf-slam")
        if slam and not self.sensors.camera_rate_hz and self.replay is None:
            raise ValueError(
                f"vehicle.estimator = {self.vehicle.estimator!r} needs a camera: set sensors.camera_rate_hz (e.g. 10)"
            )
        visual = self.vehicle.odometry == "visual" or self.vehicle.visual_odometry_vehicles
        if visual and not self.sensors.camera_rate_hz:
            raise ValueError("visual odometry needs a camera: set sensors.camera_rate_hz (e.g. 10)")
        if visual and self.vehicle.fusion_horizon_s < 1.0 / self.sensors.camera_rate_hz:
            raise ValueError(
                "visual odometry's motion arrives one camera period late: vehicle.fusion_horizon_s must be at "
                f"least the camera period ({1.0 / self.sensors.camera_rate_hz:g} s)"
            )
        unknown = sorted(set(self.vehicle.visual_odometry_vehicles) - set(range(1, self.world.vehicles + 1)))
        if unknown:
            raise ValueError(f"vehicle.visual_odometry_vehicles names vehicles not in the swarm: {unknown}")
        if self.vehicle.estimator == "known-map" and not self.vehicle.landmarks:
            raise ValueError("vehicle.estimator = 'known-map' needs the map: vehicle.landmarks")
        return self

    @model_validator(mode="after")
    def _replay_fits(self) -> SwarmConfig:
        replay = self.replay
        if replay is None and (
            self.sensors.odom_turn_sigma_rad or self.sensors.odom_travel_sigma_m or self.sensors.unmodelled_sigma_m
        ):
            raise ValueError(
                "sensors.odom_turn_sigma_rad, odom_travel_sigma_m and unmodelled_sigma_m describe a replayed "
                "robot's data; the simulated world makes no such error, so a filter told of it would be "
                "told wrong (leave them 0)"
            )
        if replay is None:
            return self
        if self.world.vehicles != len(replay.robots):
            raise ValueError(f"a replay of robots {list(replay.robots)} needs world.vehicles = {len(replay.robots)}")
        low, high = replay.calibration_s
        overlaps = replay.start_s < high and replay.start_s + self.clock.duration_s > low
        if overlaps and not replay.calibrated_elsewhere:
            raise ValueError(
                f"the replayed window [{replay.start_s:g}, {replay.start_s + self.clock.duration_s:g}] s "
                f"overlaps the calibration interval [{low:g}, {high:g}] s: nothing calibrated is scored"
            )
        return self

    def dump(self, path: Path) -> None:
        path.write_text(json.dumps(self.model_dump(mode="json"), indent=2) + "\n")

    def for_vehicle(self) -> VehicleProcessConfig:
        """All a vehicle process is given: nothing here determines truth (no world seed, no
        trajectories, no start pads); the same for every world seed."""
        return VehicleProcessConfig(
            name=self.name,
            vehicles=self.world.vehicles,
            bus=self.bus,
            clock=VehicleClock(mode=self.clock.mode, speed=self.clock.speed),
            sensors=self.sensors,
            vehicle=self.vehicle,
            altitude_m=self.world.altitude_m,
            fault_seed=self.fault_seed,
            faults=tuple(f for f in self.faults if f.kind in LINK_KINDS + BEHAVIOUR_KINDS),
        )


class VehicleClock(_Strict):
    mode: Literal["lockstep", "realtime"] = "lockstep"
    speed: float = Field(1.0, gt=0, le=1000)


class VehicleProcessConfig(_Strict):
    """One vehicle process's configuration: its sensors' datasheet (``sensors``), its estimator and
    loop settings, the flight altitude, the swarm size (valid neighbour ids) and the link faults of
    the plan with their seed. Launch prior, sensor data and the rest of the plan come over the bus."""

    name: str = Field("run", pattern=r"^[A-Za-z0-9_.\-]+$")
    vehicles: int = Field(5, ge=1, le=250)
    bus: BusConfig = BusConfig()
    clock: VehicleClock = VehicleClock()
    sensors: SensorSpec = SensorSpec()
    vehicle: VehicleConfig = VehicleConfig()
    altitude_m: float = Field(30.0, ge=0)
    fault_seed: int = Field(1, ge=0, le=2**63 - 1)
    faults: tuple[Fault, ...] = ()

    def dump(self, path: Path) -> None:
        path.write_text(json.dumps(self.model_dump(mode="json"), indent=2) + "\n")


def _validated(model: type[_Strict], data: dict) -> _Strict:
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or model.__name__
        raise ConfigError(f"invalid configuration: {where}: {first['msg']}") from None


def build_config(data: dict) -> SwarmConfig:
    """A validated SwarmConfig from a nested dict; ConfigError names the first bad field."""
    return _validated(SwarmConfig, data)


def _read_json(path: Path, env: dict[str, str], vehicles_at: tuple[str, ...]) -> dict:
    """A config file as a dict, with ``SWARMLOC_VEHICLES`` (compose scales the vehicle service with
    it) written at ``vehicles_at``."""
    try:
        data = json.loads(Path(path).read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read config {path}: {exc}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"config {path} must hold a JSON object")
    if env.get("SWARMLOC_VEHICLES"):
        if not (env["SWARMLOC_VEHICLES"].isascii() and env["SWARMLOC_VEHICLES"].isdigit()):
            raise ConfigError(f"SWARMLOC_VEHICLES must be a number of vehicles, got {env['SWARMLOC_VEHICLES']!r}")
        target = data
        for part in vehicles_at[:-1]:
            target = target.setdefault(part, {})
            if not isinstance(target, dict):
                raise ConfigError(f"config {path}: {part} must be an object")
        target[vehicles_at[-1]] = int(env["SWARMLOC_VEHICLES"])
    return data


def load_config(path: Path, env: dict[str, str] | None = None) -> SwarmConfig:
    """Read a swarm config JSON written by :meth:`SwarmConfig.dump` (or by hand)."""
    env = os.environ if env is None else env
    return build_config(_read_json(path, env, ("world", "vehicles")))


def load_vehicle_config(path: Path, env: dict[str, str] | None = None) -> VehicleProcessConfig:
    """Read a vehicle process config JSON written by :meth:`VehicleProcessConfig.dump`."""
    env = os.environ if env is None else env
    return _validated(VehicleProcessConfig, _read_json(path, env, ("vehicles",)))
