"""What a replay of a recorded data set needs to know (``SwarmConfig.replay``): where the data set
is, which of its robots fly as which vehicles, the window of it that is replayed, and the interval
the sensor datasheet was calibrated on (never scored: the window must start after it ends)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator


class CameraReadout(BaseModel):
    """How one robot's camera misreads what it sees, calibrated against ground truth
    (sim.mrclam_camera): a target at true range r and bearing b reads the range
    r (1 + scale + tilt b + curvature b^2) + offset_m, with a scale and an offset for landmarks and
    for robots (their barcodes differ in size), and the bearing b + bearing_offset_rad +
    bearing_scale b + bearing_curvature b^2, with b taken no further than span_rad off the axis in the
    curves (they are fitted there, not beyond). All zero: read as seen."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    landmark_scale: float = Field(0.0, ge=-0.5, le=0.5, description="landmark ranges read long by this fraction")
    landmark_offset_m: float = Field(0.0, ge=-1.0, le=1.0, description="and by this much (m)")
    robot_scale: float = Field(0.0, ge=-0.5, le=0.5, description="robot ranges read long by this fraction")
    robot_offset_m: float = Field(0.0, ge=-1.0, le=1.0, description="and by this much (m)")
    tilt: float = Field(0.0, ge=-1.0, le=1.0, description="range read long by this fraction per rad of bearing")
    curvature: float = Field(0.0, ge=-5.0, le=5.0, description="and per rad^2 of bearing squared")
    bearing_offset_rad: float = Field(0.0, ge=-0.5, le=0.5)
    bearing_scale: float = Field(0.0, ge=-0.5, le=0.5, description="bearing read too wide by this fraction")
    bearing_curvature: float = Field(0.0, ge=-5.0, le=5.0, description="rad per rad^2 of bearing squared")
    span_rad: float = Field(
        0.0, ge=0.0, le=3.2, description="the curves hold within +-span_rad of bearing (the fitted sightings')"
    )


class ReplayConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    kind: str = Field("mrclam", pattern=r"^mrclam$", description="data set format (UTIAS MRCLAM, data sets 1-9)")
    dataset: str = Field(min_length=1, description="the data set's directory or its .tar.xz")
    robots: tuple[int, ...] = Field(
        (1, 2, 3, 4, 5), min_length=1, max_length=5, description="robots replayed, in order: vehicle 1 is the first"
    )
    start_s: float = Field(120.0, ge=0, le=1e6, description="replay from this data set time (s after its start)")
    calibration_s: tuple[float, float] = Field(
        (0.0, 120.0),
        description="data set interval the noise datasheet "
        "was calibrated on [s]; the replayed window may not overlap it",
    )
    calibration_file: str = Field(
        "", max_length=4096, description="the file the datasheet was read from ('': calibrated on calibration_s)"
    )
    calibrated_elsewhere: bool = Field(
        False,
        description="the datasheet was fitted on another data set (calibration_s is that one's): "
        "the whole of this one may be replayed",
    )
    odom_lag_s: float = Field(
        0.0,
        ge=0,
        le=1,
        description="the robots follow an odometry command this much "
        "later (calibrated); the replay stamps each command when it takes effect",
    )
    camera_latency_s: float = Field(
        0.0,
        ge=0,
        le=1,
        description="a sighting was taken this much before its "
        "stamp (calibrated); the replay stamps each when it was taken",
    )
    sighting_sigmas: tuple[tuple[float, float], ...] = Field(
        (),
        description="per replayed robot, its camera's "
        "(range sigma per metre of range, bearing sigma rad), "
        "calibrated; empty: the datasheet's range_sigma_m "
        "(m) and bearing_sigma_rad",
    )
    readouts: tuple[CameraReadout, ...] = Field(
        (),
        description="per replayed robot, how its camera misreads range and bearing (calibrated); the "
        "replay reads each sighting back through it, as a camera driver applies its calibration; "
        "empty: sightings as recorded",
    )
    withhold_landmarks: tuple[int, ...] = Field(
        (), description="robots whose landmark sightings are withheld (they localize from odometry and the others)"
    )
    relay_sightings: bool = Field(
        True,
        description="each robot sighting is also sent to the robot seen (``seen`` "
        "rows), as the observer's radio would pass it on; cooperative vehicles fuse it",
    )

    @model_validator(mode="after")
    def _sane(self) -> ReplayConfig:
        if any(r not in (1, 2, 3, 4, 5) for r in self.robots) or len(set(self.robots)) != len(self.robots):
            raise ValueError(f"robots must be distinct robots 1-5, got {list(self.robots)}")
        if any(r not in self.robots for r in self.withhold_landmarks):
            raise ValueError(
                f"withhold_landmarks {list(self.withhold_landmarks)} names robots not replayed ({list(self.robots)})"
            )
        if self.sighting_sigmas and (
            len(self.sighting_sigmas) != len(self.robots) or any(not (r > 0 and b > 0) for r, b in self.sighting_sigmas)
        ):
            raise ValueError("sighting_sigmas needs one positive (range, bearing) pair per replayed robot")
        if self.readouts and len(self.readouts) != len(self.robots):
            raise ValueError("readouts needs one camera readout per replayed robot")
        low, high = self.calibration_s
        if not 0 <= low < high:
            raise ValueError(f"calibration_s must be an interval [start, end] with 0 <= start < end, got {[low, high]}")
        return self

    def vehicle_of(self, robot: int) -> int | None:
        """The vehicle id a robot flies as (None: not replayed)."""
        return self.robots.index(robot) + 1 if robot in self.robots else None
