"""Trajectories as input laws ``(t, pose) -> (speed, yaw rate)`` and non-overlapping start pads."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np


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
        x, y, heading = pose.tolist()
        target_x, target_y = self._points[self._index(x, y)]
        error = (math.atan2(target_y - y, target_x - x) - heading + math.pi) % (2.0 * math.pi) - math.pi
        limit = self.max_yaw_rate_radps
        return self.speed_mps, min(max(self.gain_per_s * error, -limit), limit)

    @cached_property
    def _points(self) -> list[tuple[float, float]]:
        return [tuple(point) for point in np.asarray(self.points, dtype=float).tolist()]

    def _index(self, x: float, y: float) -> int:
        # The target is the nearest waypoint's successor, so the law needs no hidden state.
        distances = [math.hypot(px - x, py - y) for px, py in self._points]
        nearest = distances.index(min(distances))
        return (nearest + 1) % len(distances) if distances[nearest] < 4 * self.reach_m else nearest


def make_trajectory(
    kind: str, *, centre_m: np.ndarray, speed_mps: float, radius_m: float, rng: np.random.Generator
) -> tuple[object, np.ndarray]:
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
