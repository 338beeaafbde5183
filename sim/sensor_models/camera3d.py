"""The world's 3-D camera (bus.sensors.camera3d): each vehicle a UAV flying ``height_m`` over the
rolling relief (sim.relief.rolling_hills) at its planar pose, its camera looking along its heading
``pitch_deg`` below the horizon, the paper's K. The ground carries trackable points (one per
1 / ``landmarks_per_m2`` m^2 over the swarm's area, 0-4 m above the relief, drawn once from the
world's seed); a frame is the points in view within ``see_m``, each with its track's id (a perfect
tracker: the id is the point's) and its pixel with noise. Richer than the vehicle's datasheet: one
point in a hundred is a tracker's slip, 5-20 px off its feature. The attitude sensor's heading and
the inertial displacement since the frame ``baseline_s`` earlier come with their own noise (a scale
error drawn per frame and white noise per axis). Pure but for the vehicles' recent positions it
keeps (for the displacement)."""

from __future__ import annotations

from collections import deque

import numpy as np

from bus.angles import wrap_angle
from bus.config import SwarmConfig
from bus.pads import start_pads
from bus.sensors.camera3d import Camera3dSpec, look
from sim.pinhole import Pinhole
from sim.relief import rolling_hills

SLIP_RATE, SLIP_PX = 0.01, (5.0, 20.0)
MARGIN_M = 150.0  # of trackable ground beyond the trajectories' reach


def landmark_field(config: SwarmConfig, spec: Camera3dSpec) -> np.ndarray:
    """The trackable points (m, 3) over the swarm's area: its start pads and a trajectory's reach
    (two circles of ``radius_m``) around each, and MARGIN_M more."""
    world = config.world
    pads = start_pads(world.vehicles, world.spacing_m)
    reach = 2.0 * world.radius_m + MARGIN_M
    low, high = pads.min(axis=0) - reach, pads.max(axis=0) + reach
    rng = np.random.default_rng([world.seed, 3, 3])
    count = int(np.prod(high - low) * spec.landmarks_per_m2)
    xy = rng.uniform(low, high, (count, 2))
    return np.column_stack([xy, rolling_hills(xy) + rng.uniform(0.0, 4.0, count)])


def camera_position(pose: np.ndarray, spec: Camera3dSpec) -> np.ndarray:
    """Where the camera is (3,) m for the planar pose [x, y, theta]: ``height_m`` over the relief."""
    xy = np.asarray(pose[:2], float)
    return np.array([xy[0], xy[1], float(rolling_hills(xy)) + spec.height_m])


def height_above_launch(xy: np.ndarray, launch_xy: np.ndarray) -> np.ndarray:
    """How high (n,) m UAVs at ``xy`` (n, 2) fly above where they launched, ``launch_xy`` (n, 2): each
    keeps its height over the relief (``camera_position``), so it climbs and descends with it."""
    return rolling_hills(np.asarray(xy, float)) - rolling_hills(np.asarray(launch_xy, float))


class Camera3dModel:
    """Measures every vehicle's frames (module docstring); built once per world."""

    def __init__(self, config: SwarmConfig) -> None:
        self.spec: Camera3dSpec = config.sensors.camera3d
        self.points = landmark_field(config, self.spec)
        self.camera = Pinhole.paper()
        self._history: dict[int, deque] = {}  # vehicle -> (stamp us, camera position) of recent frames

    def measure(
        self, vehicle_id: int, t_us: int, pose: np.ndarray, spec: Camera3dSpec, rng: np.random.Generator
    ) -> np.ndarray:
        """One frame's rows (k, 8) of the vehicle at ``pose`` [x, y, theta] (bus.sensors.camera3d)."""
        C = camera_position(pose, spec)
        rotation = look(float(pose[2]), np.deg2rad(spec.pitch_deg))
        near_ids = np.flatnonzero(np.abs(self.points[:, :2] - C[:2]).max(axis=1) <= spec.see_m)
        near = self.points[near_ids]
        pixels, depth = self.camera.project(rotation, C, near)
        width, height = self.camera.size
        seen = (depth > 0.5) & (np.linalg.norm(near - C, axis=1) <= spec.see_m)
        seen &= (pixels[:, 0] >= 0) & (pixels[:, 0] < width) & (pixels[:, 1] >= 0) & (pixels[:, 1] < height)
        ids = near_ids[seen]
        uv = pixels[seen] + rng.normal(0.0, spec.pixel_sigma_px, (len(ids), 2))
        slips = rng.random(len(ids)) < SLIP_RATE
        angle = rng.uniform(0.0, 2.0 * np.pi, len(ids))
        length = rng.uniform(*SLIP_PX, len(ids))
        uv[slips] += (length[:, None] * np.stack([np.cos(angle), np.sin(angle)], -1))[slips]
        inside = (uv[:, 0] >= 0) & (uv[:, 0] <= width) & (uv[:, 1] >= 0) & (uv[:, 1] <= height)
        heading = wrap_angle(float(pose[2]) + spec.heading_sigma_rad * float(rng.standard_normal()))
        displacement, span_s = self._displacement(vehicle_id, t_us, C, spec, rng)
        rows = np.empty((int(inside.sum()), 8))
        rows[:, 0], rows[:, 1:3], rows[:, 3] = ids[inside], uv[inside], heading
        rows[:, 4:7], rows[:, 7] = displacement, span_s
        return rows

    def _displacement(
        self, vehicle_id: int, t_us: int, C: np.ndarray, spec: Camera3dSpec, rng: np.random.Generator
    ) -> tuple[np.ndarray, float]:
        """The measured displacement since the frame ``baseline_s`` ago (3,) and that span (0 and 0 when
        this vehicle had no frame then), the draws made whether or not there is one."""
        scale = 1.0 + spec.baseline_scale_sigma * float(rng.standard_normal())
        noise = spec.baseline_sigma_m * rng.standard_normal(3)
        history = self._history.setdefault(vehicle_id, deque())
        history.append((t_us, C))
        span_us = round(spec.baseline_s * 1e6)
        while history and history[0][0] < t_us - span_us:
            history.popleft()
        if history[0][0] != t_us - span_us:
            return np.zeros(3), 0.0
        return scale * (C - history[0][1]) + noise, spec.baseline_s
