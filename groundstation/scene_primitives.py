"""The Foxglove scene primitives the recording draws with (``fm`` is ``foxglove.messages``, imported
by the caller): poses, arrows, labels, closed lines on the ground, timestamps, and the 3-sigma
ellipse of a position covariance. Pure."""

from __future__ import annotations

import functools
import math

import numpy as np

from bus.faults import BY_KIND

ELLIPSE_POINTS = 36


def ellipse_xy(centre: np.ndarray, covariance: np.ndarray, sigmas: float = 3.0) -> np.ndarray:
    """Points (ELLIPSE_POINTS, 2) of the ``sigmas`` ellipse of a 2x2 position covariance, rotated by
    its eigenvectors."""
    values, vectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    axes = sigmas * np.sqrt(np.maximum(values, 0.0))
    return centre + (_unit_circle(ELLIPSE_POINTS) * axes) @ vectors.T


@functools.cache
def _unit_circle(points: int) -> np.ndarray:
    """(points, 2) cos and sin of ``points`` angles evenly around the circle (read-only)."""
    angle = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    circle = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    circle.flags.writeable = False
    return circle


def pose(fm, x: float, y: float, yaw: float):
    return fm.Pose(
        position=fm.Vector3(x=float(x), y=float(y), z=0.0),
        orientation=fm.Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)),
    )


def arrow(fm, at_pose, rgb: tuple[float, float, float]):
    return fm.ArrowPrimitive(
        pose=at_pose,
        shaft_length=1.0,
        shaft_diameter=0.15,
        head_length=0.5,
        head_diameter=0.4,
        color=fm.Color(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0),
    )


def label(fm, at_pose, text: str, rgba: tuple[float, float, float, float]):
    color = fm.Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])
    return fm.TextPrimitive(pose=at_pose, billboard=True, font_size=14.0, scale_invariant=True, color=color, text=text)


def stamp(fm, stamp_us: int):
    """A foxglove Timestamp of sim time ``stamp_us``."""
    return fm.Timestamp(sec=stamp_us // 1_000_000, nsec=(stamp_us % 1_000_000) * 1000)


def loop(fm, xy: np.ndarray, rgba: tuple[float, float, float, float], thickness: float):
    """A closed line through the points ``xy`` (k, 2) on the ground."""
    return fm.LinePrimitive(
        type=fm.LinePrimitiveLineType.LineLoop,
        thickness=thickness,
        scale_invariant=True,
        points=[fm.Point3(x=a, y=b, z=0.0) for a, b in np.asarray(xy, dtype=float).tolist()],
        color=fm.Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
    )


def zone_colour(kind: str) -> tuple[float, float, float]:
    """The colour a fault zone of ``kind`` is drawn with: the kind's own marker (bus.faults), grey for
    a kind that declares none."""
    fault = BY_KIND.get(kind)
    return fault.marker if fault is not None and fault.marker is not None else (0.6, 0.6, 0.6)
