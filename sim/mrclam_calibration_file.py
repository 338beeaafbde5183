"""A datasheet calibrated from ground truth, frozen in a file: ``swarm replay calibrate`` fits it on an
interval of one data set (sim.mrclam_calibration, launch.unmodelled) and writes it; ``swarm replay
mrclam --calibration FILE`` reads it instead of calibrating, so a held-out data set, or the other half
of the same one, is replayed with numbers that never saw it. Nothing in the file is typed by hand.

The file is JSON: the data set it was fitted on (its name, and its recording's start time, which names
it whatever its file is called: the whole data set and an excerpt of it are the same recording), the
interval and robots, the swarm's datasheet (the ``sensors`` fields a replay sets), the odometry lag and
camera latency, each robot's camera sigmas and readout (how it misreads range and bearing), the
unmodelled sigma, and how much it was measured on. Reading it is total: a file that is not one is
refused with one line naming the file and what is wrong.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from bus.errors import ConfigError
from bus.replay_config import CameraReadout
from sim.mrclam import MrclamData
from sim.mrclam_calibration import Calibration

FORMAT = "swarmloc/mrclam-calibration"


class CalibratedSensors(BaseModel):
    """The datasheet fields a replay takes from the calibration (bus.config.SensorSpec's names)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    odom_speed_sigma_mps: float = Field(ge=0, le=10)
    odom_yaw_rate_sigma_radps: float = Field(ge=0, le=10)
    odom_travel_sigma_m: float = Field(ge=0, le=10)
    odom_turn_sigma_rad: float = Field(ge=0, le=10)
    range_sigma_m: float = Field(gt=0, le=100)
    bearing_sigma_rad: float = Field(gt=0, le=3.2)
    range_correlated_sigma_per_m: float = Field(ge=0, le=0.5)
    range_correlation_s: float = Field(gt=0, le=1e4)
    bearing_correlated_fraction: float = Field(ge=0, le=0.95)
    bearing_correlation_s: float = Field(gt=0, le=1e4)
    unmodelled_sigma_m: float = Field(
        0.0, ge=0, le=10, description="measured out of sample inside the interval (launch.unmodelled)"
    )


class CalibrationFile(BaseModel):
    """One calibration (module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    format: Literal["swarmloc/mrclam-calibration"] = FORMAT
    version: Literal[1] = 1
    dataset: str = Field(min_length=1, max_length=200, description="the data set's name, for people")
    recorded_at_s: float = Field(ge=0, le=1e11, description="its recording's start (Unix s): which data set it is")
    interval_s: tuple[float, float]
    robots: tuple[int, ...] = Field(min_length=1, max_length=5)
    sensors: CalibratedSensors
    odom_lag_s: float = Field(ge=0, le=1)
    camera_latency_s: float = Field(ge=0, le=1)
    sighting_sigmas: dict[int, tuple[float, float]] = Field(
        description="per robot: its camera's range sigma per metre of range and bearing sigma (rad)"
    )
    readouts: dict[int, CameraReadout] = Field(
        default_factory=dict,
        description="per robot: how its camera misreads range and bearing (none: read as recorded)",
    )
    sightings: int = Field(ge=0)
    outliers: int = Field(ge=0)
    odometry_windows: int = Field(ge=0)

    def fitted_on(self, data: MrclamData) -> bool:
        """Whether this calibration was fitted on ``data``'s recording."""
        return abs(self.recorded_at_s - data.start_s) < 1e-3

    def camera_of(self, robot: int) -> tuple[float, float]:
        if robot not in self.sighting_sigmas:
            raise ConfigError(
                f"the calibration has no camera of robot {robot} (it was fitted on robots {list(self.robots)})"
            )
        return self.sighting_sigmas[robot]

    def readout_of(self, robot: int) -> CameraReadout:
        """The robot's camera readout (identity in a file written before readouts were calibrated)."""
        self.camera_of(robot)
        return self.readouts.get(robot, CameraReadout())


def calibration_file(
    data: MrclamData,
    dataset: str,
    cal: Calibration,
    robots: tuple[int, ...],
    cameras: tuple[tuple[float, float], ...],
    unmodelled_sigma_m: float,
) -> CalibrationFile:
    """The file of calibration ``cal`` of ``robots`` on ``data`` (named ``dataset``), with each
    robot's camera sigmas (sim.mrclam_calibration.sighting_sigmas) and the unmodelled sigma
    (launch.unmodelled)."""
    fitted = {name: getattr(cal, name) for name in CalibratedSensors.model_fields if name != "unmodelled_sigma_m"}
    sensors = CalibratedSensors(**fitted, unmodelled_sigma_m=unmodelled_sigma_m)
    return CalibrationFile(
        dataset=dataset,
        recorded_at_s=data.start_s,
        interval_s=(float(cal.interval_s[0]), float(cal.interval_s[1])),
        robots=tuple(robots),
        sensors=sensors,
        odom_lag_s=cal.odom_lag_s,
        camera_latency_s=cal.camera_latency_s,
        sighting_sigmas={robot: (float(r), float(b)) for robot, (r, b) in zip(robots, cameras)},
        readouts=dict(zip(robots, cal.readouts)),
        sightings=cal.sightings,
        outliers=cal.outliers,
        odometry_windows=cal.odometry_windows,
    )


def write_calibration(path: Path, calibration: CalibrationFile) -> None:
    path.write_text(json.dumps(calibration.model_dump(mode="json"), indent=2, sort_keys=True) + "\n")


def read_calibration(path: Path) -> CalibrationFile:
    """The calibration in ``path``; ConfigError naming the file and what is wrong for anything else."""
    path = Path(path)
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"calibration file {path}: cannot read it ({exc.__class__.__name__})") from None
    try:
        return CalibrationFile.model_validate_json(text)
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(part) for part in first.get("loc", ())) or "(the file)"
        count = exc.error_count()
        raise ConfigError(
            f"calibration file {path}: {where}: {first.get('msg', 'invalid')} "
            f"({count} problem{'s' if count > 1 else ''}); write it with `swarm replay calibrate`"
        ) from None


def dataset_name(path: str | Path) -> str:
    """A data set's name from its directory or archive path (``.../MRCLAM_Dataset6.tar.xz``: MRCLAM_Dataset6)."""
    name = Path(path).name
    for suffix in (".tar.xz", ".tar.gz", ".tgz", ".tar"):
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name
