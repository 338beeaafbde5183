"""The Foxglove scene primitives the recording draws with (``fm`` is ``foxglove.messages``, imported
by the caller): poses, arrows, labels, closed lines at a height, timestamps, and the 3-sigma
ellipse of a 2 x 2 position covariance and ellipsoid of a 3 x 3 one. Pure."""

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


def ellipsoid(covariance: np.ndarray, sigmas: float = 3.0) -> tuple[np.ndarray, np.ndarray]:
    """The ``sigmas`` ellipsoid of a 3 x 3 covariance: its diameters along its principal axes (3,) m and
    the rotation to them as a quaternion (x, y, z, w) (the axes, right-handed, as the columns)."""
    values, vectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    if np.linalg.det(vectors) < 0.0:
        vectors[:, 0] = -vectors[:, 0]
    return 2.0 * sigmas * np.sqrt(np.maximum(values, 0.0)), quaternion(vectors)


def quaternion(rotation: np.ndarray) -> np.ndarray:
    """The unit quaternion (x, y, z, w) of a rotation matrix (3, 3) (Shepperd's method)."""
    m = rotation
    trace = np.trace(m)
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(m)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * math.sqrt(1.0 + m[i, i] - m[j, j] - m[k, k])
        q = [0.0, 0.0, 0.0, (m[k, j] - m[j, k]) / s]
        q[i], q[j], q[k] = 0.25 * s, (m[j, i] + m[i, j]) / s, (m[k, i] + m[i, k]) / s
    q = np.array(q)
    return q / np.linalg.norm(q)


def ellipsoid_sphere(fm, centre: np.ndarray, covariance: np.ndarray, rgba: tuple, sigmas: float = 3.0):
    """A sphere primitive drawn as the ``sigmas`` ellipsoid of a 3 x 3 position ``covariance`` (m^2)
    around ``centre`` (3,) m."""
    size, q = ellipsoid(covariance, sigmas)
    return fm.SpherePrimitive(
        pose=fm.Pose(
            position=fm.Vector3(x=float(centre[0]), y=float(centre[1]), z=float(centre[2])),
            orientation=fm.Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])),
        ),
        size=fm.Vector3(x=float(size[0]), y=float(size[1]), z=float(size[2])),
        color=fm.Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
    )


@functools.cache
def _unit_circle(points: int) -> np.ndarray:
    """(points, 2) cos and sin of ``points`` angles evenly around the circle (read-only)."""
    angle = np.linspace(0.0, 2.0 * np.pi, points, endpoint=False)
    circle = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    circle.flags.writeable = False
    return circle


def pose(fm, x: float, y: float, yaw: float, z: float = 0.0):
    """A pose at (x, y, z) m (z up), heading ``yaw`` rad about z."""
    return fm.Pose(
        position=fm.Vector3(x=float(x), y=float(y), z=float(z)),
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


def loop(fm, xy: np.ndarray, rgba: tuple[float, float, float, float], thickness: float, z: float = 0.0):
    """A closed line through the points ``xy`` (k, 2) at height ``z`` m (the ground: 0)."""
    return fm.LinePrimitive(
        type=fm.LinePrimitiveLineType.LineLoop,
        thickness=thickness,
        scale_invariant=True,
        points=[fm.Point3(x=a, y=b, z=float(z)) for a, b in np.asarray(xy, dtype=float).tolist()],
        color=fm.Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3]),
    )


def zone_colour(kind: str) -> tuple[float, float, float]:
    """The colour a fault zone of ``kind`` is drawn with: the kind's own marker (bus.faults), grey for
    a kind that declares none."""
    fault = BY_KIND.get(kind)
    return fault.marker if fault is not None and fault.marker is not None else (0.6, 0.6, 0.6)
