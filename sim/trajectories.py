"""Trajectories as input laws ``(t, pose) -> (speed, yaw rate)`` and non-overlapping start pads."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.kinematics import wrap_angle


@dataclass(frozen=True)
class Circle:
    """Constant speed on a circle of ``radius_m``, clockwise when seen from above (NED: yaw rate > 0)."""

    speed_mps: float
    radius_m: float

    def inputs(self, t_s: float, pose: np.ndarray) -> tuple[float, float]:
        return self.speed_mps, self.speed_mps / self.radius_m


@dataclass(frozen=True)
class FigureEight:
    """Two tangent circles of ``radius_m``: one lap turning right, then one lap turning left."""

    speed_mps: float
    radius_m: float

    def inputs(self, t_s: float, pose: np.ndarray) -> tuple[float, float]:
        lap_s = 2.0 * np.pi * self.radius_m / self.speed_mps
        turn = 1.0 if (t_s // lap_s) % 2 == 0 else -1.0
        return self.speed_mps, turn * self.speed_mps / self.radius_m


@dataclass(frozen=True)
class Waypoints:
    """Visit ``points`` (M, 2) in a loop, steering the heading towards the next one (P controller)."""

    speed_mps: float
    points: np.ndarray
    gain_per_s: float = 1.0
    max_yaw_rate_radps: float = 0.5
    reach_m: float = 3.0

    def inputs(self, t_s: float, pose: np.ndarray) -> tuple[float, float]:
        target = self.points[self._index(pose)]
        bearing = np.arctan2(target[1] - pose[1], target[0] - pose[0])
        yaw_rate = self.gain_per_s * float(wrap_angle(bearing - pose[2]))
        return self.speed_mps, float(np.clip(yaw_rate, -self.max_yaw_rate_radps, self.max_yaw_rate_radps))

    def _index(self, pose: np.ndarray) -> int:
        # The target is the nearest waypoint's successor, so the law needs no hidden state.
        distances = np.hypot(self.points[:, 0] - pose[0], self.points[:, 1] - pose[1])
        nearest = int(np.argmin(distances))
        return (nearest + 1) % len(self.points) if distances[nearest] < 4 * self.reach_m else nearest


def start_pads(count: int, spacing_m: float) -> np.ndarray:
    """Pad centres on a square grid, ``spacing_m`` apart: (count, 2) in m."""
    side = int(np.ceil(np.sqrt(count)))
    index = np.arange(count)
    return np.stack([(index // side) * spacing_m, (index % side) * spacing_m], axis=1).astype(float)


def make_trajectory(kind: str, *, centre_m: np.ndarray, speed_mps: float, radius_m: float,
                    rng: np.random.Generator) -> tuple[object, np.ndarray]:
    """A trajectory of ``kind`` that stays within ``radius_m`` of ``centre_m``, and its start pose (3,)."""
    if kind == "circle":
        return Circle(speed_mps, radius_m), np.array([centre_m[0], centre_m[1] - radius_m, 0.0])
    if kind == "figure8":
        return FigureEight(speed_mps, radius_m / 2), np.array([centre_m[0], centre_m[1], 0.0])
    if kind == "waypoints":
        angles = np.sort(rng.uniform(0, 2 * np.pi, 5))
        radii = rng.uniform(0.4, 1.0, 5) * radius_m
        points = centre_m + np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)
        heading = np.arctan2(points[0, 1] - centre_m[1], points[0, 0] - centre_m[0])
        return Waypoints(speed_mps, points), np.array([centre_m[0], centre_m[1], heading])
    raise ValueError(f"unknown trajectory {kind!r}; known: circle, figure8, waypoints")
