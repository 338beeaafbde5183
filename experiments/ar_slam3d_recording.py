"""A 3-D case of `swarm experiment ar-slam` as Foxglove and Lichtblick see it: ``run.mcap`` in the case's
run directory, written frame by frame while the back end flies (experiments.ar_slam3d.fly's
``on_frame``), with ``layout-lichtblick.json`` beside it. Log times are the flight's time.

Channels:

- ``/relief3d``: the ground under the flight as a mesh coloured by height, and the true track (once).
- ``/camera3d``: per frame, the estimated camera (its 3-sigma position ellipsoid and its velocity as an
  arrow), the true camera, and the observation range R as a ring at the camera's height.
- ``/map3d``: per frame, every landmark in the state as its 3-sigma ellipsoid (the principal axes of
  its 3 x 3 covariance block): long, thin ones are points triangulated over a short baseline.
- ``/track3d``: the estimated track so far, a point every ``TRACK_EVERY`` frames.
- ``/flight3d``: per frame, the position error, the position NEES (3 dof) with its 95 % band, R, the
  landmarks in the state and the frame's cost (the plots).
- ``/tf``: per frame, the frame ``camera`` at the estimated position in ``world``: the layout's 3-D
  panel follows it.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from bus.statistics import chi2_band
from experiments.ar_slam3d import RATE_HZ, ground
from groundstation import scene_primitives as sp
from groundstation.layout import Plot, lichtblick_document
from vehicle.estimators.ar_slam3d import ArSlam3d
from vehicle.models import slam3d

MCAP, LAYOUT = "run.mcap", "layout-lichtblick.json"
SIGMAS, MESH_STEP_M, MESH_MARGIN_M, TRACK_EVERY = 3.0, 5.0, 60.0, 10
TRUE_RGBA, ESTIMATED_RGBA, LANDMARK_RGBA = (0.1, 0.8, 0.2, 1.0), (0.2, 0.4, 1.0, 0.6), (1.0, 0.8, 0.2, 0.45)
SCENE_TOPICS = ("/relief3d", "/camera3d", "/map3d", "/track3d")
FLIGHT_SCHEMA = {
    "title": "swarmloc.Flight3d",
    "type": "object",
    "properties": {
        "t_s": {"type": "number", "description": "flight time (s)"},
        "error_m": {"type": "number", "description": "3-D position error (m)"},
        "nees": {"type": "number", "description": "position NEES, 3 dof"},
        "nees_band_low": {"type": "number", "description": "two-sided 95 % band of one 3-dof NEES"},
        "nees_band_high": {"type": "number"},
        "radius_m": {"type": "number", "description": "the observation range R (m)"},
        "landmarks": {"type": "integer", "description": "landmarks in the state"},
        "frame_ms": {"type": "number", "description": "the back end's time for the frame (ms)"},
    },
}


def relief_mesh(positions: np.ndarray, step_m: float = MESH_STEP_M) -> tuple[np.ndarray, np.ndarray]:
    """The ground under the flight's true positions (k, 3), MESH_MARGIN_M around them: triangle
    vertices (t, 3, 3) m and each vertex's grey level (t, 3) in [0, 1] by height."""
    low, high = positions[:, :2].min(axis=0) - MESH_MARGIN_M, positions[:, :2].max(axis=0) + MESH_MARGIN_M
    xs, ys = np.arange(low[0], high[0] + step_m, step_m), np.arange(low[1], high[1] + step_m, step_m)
    gx, gy = np.meshgrid(xs, ys)
    grid = np.stack([gx, gy, ground(np.stack([gx, gy], axis=-1))], axis=-1)  # (ny, nx, 3)
    a, b, c, d = grid[:-1, :-1], grid[:-1, 1:], grid[1:, 1:], grid[1:, :-1]
    triangles = np.concatenate([np.stack([a, b, c], -2), np.stack([a, c, d], -2)]).reshape(-1, 3, 3)
    z = triangles[..., 2]
    shade = 0.25 + 0.5 * (z - z.min()) / max(float(np.ptp(z)), 1e-9)
    return triangles, shade


class FlightRecording:
    """Writes one flight's channels (module docstring) to ``run_dir``/run.mcap as its frames come; the
    true positions (frames + 1, 3) are the flight's (experiments.ar_slam3d.world), frame k at k / RATE_HZ."""

    def __init__(self, run_dir: Path, positions: np.ndarray) -> None:
        import foxglove
        from foxglove import messages as fm
        from foxglove.channels import FrameTransformChannel, SceneUpdateChannel

        self.fm, self.positions = fm, positions
        self.context = foxglove.Context()
        self.writer = foxglove.open_mcap(run_dir / MCAP, context=self.context)
        self.channels = {topic: SceneUpdateChannel(topic, context=self.context) for topic in SCENE_TOPICS}
        self.flight = foxglove.Channel("/flight3d", schema=FLIGHT_SCHEMA, context=self.context)
        self.tf = FrameTransformChannel("/tf", context=self.context)
        self.band = chi2_band(3)
        self.track: list[np.ndarray] = []
        self._log("/relief3d", 0, self._relief())
        (run_dir / LAYOUT).write_text(layout())

    def frame(self, k: int, slam: ArSlam3d, frame_ms: float) -> None:
        """Frame ``k`` after the back end took it (``fly``'s ``on_frame``)."""
        stamp_us = round(k * 1e6 / RATE_HZ)
        p, P = slam.x[:3], slam.P[:3, :3]
        error = p - self.positions[k]
        nees = float(error @ np.linalg.solve(P, error))
        record = {
            "t_s": stamp_us * 1e-6,
            "error_m": float(np.linalg.norm(error)),
            "radius_m": float(slam.book.radius_m),
            "landmarks": slam3d.landmarks(slam.x),
            "frame_ms": float(frame_ms),
            "nees_band_low": self.band[0],
            "nees_band_high": self.band[1],
        }
        if math.isfinite(nees):  # a missing value is a field left out (groundstation.plot_records)
            record["nees"] = nees
        self.flight.log(record, log_time=stamp_us * 1000)
        follow = self.fm.FrameTransform(
            timestamp=sp.stamp(self.fm, stamp_us),
            parent_frame_id="world",
            child_frame_id="camera",
            translation=_vector(self.fm, p),
            rotation=_orientation(self.fm, np.array([0.0, 0.0, 0.0, 1.0])),
        )
        self.tf.log(follow, log_time=stamp_us * 1000)
        self._log("/camera3d", stamp_us, self._camera(slam, self.positions[k]))
        self._log("/map3d", stamp_us, [self._ellipsoid(x, c, LANDMARK_RGBA) for x, c in _landmark_blocks(slam)])
        if k % TRACK_EVERY == 0:
            self.track.append(p.copy())
            self._log("/track3d", stamp_us, [self._line(np.array(self.track), ESTIMATED_RGBA, 2.0)], entity="track")

    def close(self) -> None:
        self.writer.close()

    def _log(self, topic: str, stamp_us: int, primitives: list, entity: str | None = None) -> None:
        """One entity of ``primitives`` (sorted into the entity's lists by kind) on ``topic``."""
        fm = self.fm
        kinds: dict[str, list] = {"spheres": [], "arrows": [], "lines": [], "triangles": []}
        for primitive in primitives:
            kinds[_KINDS[type(primitive).__name__]].append(primitive)
        scene = fm.SceneEntity(
            timestamp=sp.stamp(fm, stamp_us), frame_id="world", id=entity or topic.strip("/"), **kinds
        )
        self.channels[topic].log(fm.SceneUpdate(entities=[scene]), log_time=stamp_us * 1000)

    def _relief(self) -> list:
        fm = self.fm
        triangles, shade = relief_mesh(self.positions)
        points = [fm.Point3(x=float(x), y=float(y), z=float(z)) for x, y, z in triangles.reshape(-1, 3)]
        colors = [fm.Color(r=float(g), g=float(g), b=float(g), a=1.0) for g in shade.ravel()]
        mesh = fm.TriangleListPrimitive(pose=sp.pose(fm, 0.0, 0.0, 0.0), points=points, colors=colors)
        return [mesh, self._line(self.positions, TRUE_RGBA, 1.5)]

    def _camera(self, slam: ArSlam3d, truth: np.ndarray) -> list:
        fm = self.fm
        p, v = slam.x[:3], slam.x[3:6]
        heading = math.atan2(v[1], v[0])
        climb = math.atan2(v[2], math.hypot(v[0], v[1]))
        arrow_pose = fm.Pose(position=_vector(fm, p), orientation=_orientation(fm, _yaw_pitch(heading, -climb)))
        arrow = fm.ArrowPrimitive(
            pose=arrow_pose,
            shaft_length=4.0,
            shaft_diameter=0.4,
            head_length=1.5,
            head_diameter=1.0,
            color=_color(fm, ESTIMATED_RGBA[:3] + (1.0,)),
        )
        true_camera = fm.SpherePrimitive(
            pose=fm.Pose(position=_vector(fm, truth), orientation=_orientation(fm, np.array([0, 0, 0, 1.0]))),
            size=fm.Vector3(x=1.0, y=1.0, z=1.0),
            color=_color(fm, TRUE_RGBA),
        )
        angles = np.linspace(0.0, 2.0 * np.pi, 73)
        ring = p + slam.book.radius_m * np.stack([np.cos(angles), np.sin(angles), np.zeros_like(angles)], -1)
        return [
            self._ellipsoid(p, slam.P[:3, :3], ESTIMATED_RGBA),
            arrow,
            true_camera,
            self._line(ring, (1.0, 1.0, 1.0, 0.5), 1.0),
        ]

    def _ellipsoid(self, centre: np.ndarray, covariance: np.ndarray, rgba: tuple) -> Any:
        return sp.ellipsoid_sphere(self.fm, centre, covariance, rgba, SIGMAS)

    def _line(self, points: np.ndarray, rgba: tuple, thickness: float) -> Any:
        fm = self.fm
        return fm.LinePrimitive(
            type=fm.LinePrimitiveLineType.LineStrip,
            thickness=thickness,
            scale_invariant=True,
            points=[_point(fm, q) for q in points],
            color=_color(fm, rgba),
        )


_KINDS = {
    "SpherePrimitive": "spheres",
    "ArrowPrimitive": "arrows",
    "LinePrimitive": "lines",
    "TriangleListPrimitive": "triangles",
}


def _landmark_blocks(slam: ArSlam3d) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each landmark in the state: its position (3,) and its covariance block (3, 3)."""
    out = []
    for j in range(slam3d.landmarks(slam.x)):
        rows = slam3d.landmark_slice(j)
        out.append((slam.x[rows], slam.P[rows, rows]))
    return out


def _yaw_pitch(yaw: float, pitch: float) -> np.ndarray:
    """The quaternion (x, y, z, w) of a heading ``yaw`` then a ``pitch`` about the new y axis (an arrow
    along x pointed at that heading and that far below the horizon)."""
    cy, sy, cp, sp_ = math.cos(yaw / 2), math.sin(yaw / 2), math.cos(pitch / 2), math.sin(pitch / 2)
    return np.array([-sy * sp_, cy * sp_, sy * cp, cy * cp])


def _vector(fm, p) -> Any:
    return fm.Vector3(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def _point(fm, p) -> Any:
    return fm.Point3(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def _orientation(fm, q: np.ndarray) -> Any:
    return fm.Quaternion(x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))


def _color(fm, rgba: tuple) -> Any:
    return fm.Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def layout() -> str:
    """The Lichtblick layout of a flight: the scene following the camera (seen from behind and above),
    beside the position error, the NEES against its band, and R with the landmarks in the state."""
    low, high = chi2_band(3)
    plots = (
        Plot("error", "position error [m]", (("3-D error", "/flight3d.error_m"),)),
        Plot(
            "nees",
            "position NEES (3 dof)",
            (("NEES", "/flight3d.nees"), ("95 % low", f"{low:.4f}"), ("95 % high", f"{high:.4f}")),
        ),
        Plot(
            "range",
            "range R [m], landmarks in the state",
            (("R", "/flight3d.radius_m"), ("landmarks", "/flight3d.landmarks")),
        ),
    )
    camera = {
        "distance": 80.0,
        "perspective": True,
        "phi": 60.0,
        "target": [0.0, 0.0, 0.0],
        "targetOffset": [0.0, 0.0, 0.0],
        "targetOrientation": [0.0, 0.0, 0.0, 1.0],
        "thetaOffset": 30.0,
        "fovy": 45.0,
        "near": 0.5,
        "far": 5000.0,
    }
    topics = {topic: {"visible": True} for topic in SCENE_TOPICS}
    return lichtblick_document(
        "flight",
        camera,
        topics,
        plots,
        None,
        follow=("camera", "follow-position"),
        hidden_frames=("camera",),
        preload_transforms=True,
    )
