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

from pydantic import Field, ValidationError, model_validator

from bus.clock_config import ClockConfig as ClockConfig
from bus.clock_config import ClockMode as ClockMode
from bus.errors import ConfigError
from bus.estimators import ESTIMATORS, NEEDS
from bus.faults import BEHAVIOUR_KINDS, LINK_KINDS, Fault, check_fault, named
from bus.replay_config import ReplayConfig
from bus.sensor_config import HONEST_DATASHEET as HONEST_DATASHEET
from bus.sensor_config import HONEST_WORLD as HONEST_WORLD
from bus.sensor_config import SensorSpec as SensorSpec
from bus.sensor_config import SensorTruth as SensorTruth
from bus.strict_model import Strict as _Strict
from bus.topics import Topic
from bus.vehicle_config import ArSlamConfig as ArSlamConfig
from bus.vehicle_config import VehicleConfig as VehicleConfig
from bus.view_config import ViewConfig as ViewConfig


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
            (Topic.ODOM, self.sensors.odom_rate_hz),
            (Topic.GNSS, self.sensors.gnss_rate_hz),
            (Topic.RANGING, self.sensors.ranging_rate_hz),
            *([(Topic.CAMERA, self.sensors.camera_rate_hz)] if self.sensors.camera_rate_hz else []),
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
    def _estimator_has_what_it_needs(self) -> SwarmConfig:
        has = {
            "camera": bool(self.sensors.camera_rate_hz) or self.replay is not None,
            "map": bool(self.vehicle.landmarks),
            "camera3d": bool(self.sensors.camera3d.rate_hz),
        }
        for need in sorted(ESTIMATORS[self.vehicle.estimator].needs):
            if not has[need]:
                raise ValueError(f"vehicle.estimator = {self.vehicle.estimator!r} needs {NEEDS[need]}")
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
        touch_s = 1e-6  # windows that meet at one instant (a fold's halves) do not overlap
        overlaps = replay.start_s < high - touch_s and replay.start_s + self.clock.duration_s > low + touch_s
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
    mode: ClockMode = ClockMode.LOCKSTEP
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
