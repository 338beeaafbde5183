"""``camera3d``: the AR-EKF-SLAM paper's camera on a UAV flying over terrain with relief, as a tracked
feature stream. Each frame is its points, one row each: the track's id, its pixel (u, v) under the
paper's K (640 x 480), and what the frame shares with its other rows: the attitude sensor's heading
(the camera looks along it, ``pitch_deg`` below the horizon), and the displacement since the frame
``baseline_s`` earlier as the vehicle's inertial sensors measure it (the paper takes the scale of
visual odometry from an inertial unit; ``baseline_s`` 0: no earlier frame yet). The world stands in
for the front end's tracker (sim.sensor_models.camera3d); the vehicle triangulates and maps
(vehicle.estimators.ar_ekf_slam_3d). A sensor added by the recipe (docs/tutorial/adding-a-sensor.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from pydantic import Field

from bus.sensors.base import SensorKind, SensorSpec

WIDTH_PX, HEIGHT_PX = 640, 480
PAPER_K = np.array([[1015.78212, 0.0, 320.03704], [0.0, 1012.65800, 240.40334], [0.0, 0.0, 1.0]])  # the paper's
MAX_TRACK_ID = 999_999
MAX_BASELINE_M = 1000.0


def look(yaw: float, pitch: float) -> np.ndarray:
    """R_wc (3, 3): camera axes (x right, y down, z forward) in the world (z up), the optical axis at
    heading ``yaw`` (rad, forward = (cos, sin) in the plane, the vehicles' convention) and ``pitch``
    below the horizon: how the camera is mounted, for the world and the vehicle alike."""
    forward = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), -np.sin(pitch)])
    right = np.array([np.sin(yaw), -np.cos(yaw), 0.0])
    down = np.cross(forward, right)
    return np.column_stack([right, down, forward])


class Camera3dSpec(SensorSpec):
    rate_hz: float = Field(0.0, ge=0, le=30, description="frames per second (0: no 3-D camera)")
    height_m: float = Field(15.0, gt=0, le=500, description="the UAV's height over the relief (m)")
    pitch_deg: float = Field(50.0, ge=5, le=85, description="the camera's axis below the horizon (deg)")
    pixel_sigma_px: float = Field(1.0, gt=0, le=20, description="a tracked point's pixel noise (px)")
    heading_sigma_rad: float = Field(0.005, gt=0, le=0.5, description="the attitude sensor's heading noise (rad)")
    baseline_s: float = Field(1.0, gt=0, le=10, description="the earlier frame each frame is triangulated with (s)")
    baseline_sigma_m: float = Field(0.02, ge=0, le=10, description="the inertial displacement's noise per axis (m)")
    baseline_scale_sigma: float = Field(0.01, ge=0, le=0.5, description="and its scale error's sigma")
    see_m: float = Field(60.0, gt=1, le=500, description="the farthest point tracked (m)")
    landmarks_per_m2: float = Field(0.2, gt=0, le=1, description="trackable points on the ground per m^2")


@dataclass(frozen=True)
class TrackedPoint:
    """One tracked point of a frame: its track's id, its pixel (col, row), the attitude sensor's
    heading (rad, the planar filters' convention), and the inertial displacement (3,) m since the frame
    ``baseline_s`` earlier (0: none)."""

    vehicle_id: int
    stamp_us: int
    seq: int
    track_id: int
    pixel: tuple[float, float]
    heading_rad: float
    baseline_m: tuple[float, float, float]
    baseline_s: float


class Camera3d(SensorKind):
    topic: ClassVar[str] = "camera3d"
    width: ClassVar[int] = 8  # track id, u px, v px, heading rad, displacement (3) m, baseline s
    max_rows: ClassVar[int] = 20_000
    max_abs: ClassVar[float] = 1e6
    several: ClassVar[bool] = True  # a frame is several rows with one stamp
    Spec: ClassVar[type[SensorSpec]] = Camera3dSpec
    world_model: ClassVar[str] = "sim.sensor_models.camera3d:Camera3dModel"
    part: ClassVar[str] = "vehicle.estimators.camera3d:Camera3dUnused"

    @classmethod
    def message(cls, vehicle_id: int, stamp_us: int, seq: int, row: np.ndarray) -> TrackedPoint:
        return TrackedPoint(
            vehicle_id,
            stamp_us,
            seq,
            int(row[0]),
            (float(row[1]), float(row[2])),
            float(row[3]),
            (float(row[4]), float(row[5]), float(row[6])),
            float(row[7]),
        )

    @classmethod
    def flaw(cls, rows: np.ndarray) -> str | None:
        ident = rows[:, 0]
        if ((ident != np.round(ident)) | (ident < 0) | (ident > MAX_TRACK_ID)).any():
            return f"track ids integers 0-{MAX_TRACK_ID}"
        if ((rows[:, 1] < 0) | (rows[:, 1] > WIDTH_PX) | (rows[:, 2] < 0) | (rows[:, 2] > HEIGHT_PX)).any():
            return f"pixels inside the {WIDTH_PX} x {HEIGHT_PX} frame"
        if (np.abs(rows[:, 3]) > math.pi + 1e-9).any():
            return "a heading within +-pi rad"
        if (np.abs(rows[:, 4:7]) > MAX_BASELINE_M).any() or ((rows[:, 7] < 0) | (rows[:, 7] > 10)).any():
            return f"a displacement within +-{MAX_BASELINE_M:g} m over 0-10 s"
        return None
