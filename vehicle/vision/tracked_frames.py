"""A 3-D camera's tracked frames (bus.sensors.camera3d) turned into body-frame points: each point two
frames ``span_s`` apart both track is triangulated from its two pixels (vehicle.vision.triangulation,
the paper's four linear equations), the cameras' rotations from the attitude sensor's headings (the
camera looks along the heading, ``pitch_deg`` below the horizon) and the baseline from the inertial
displacement between the frames.

What the points' errors are made of: each pixel's noise, independent from point to point (the
triangulation's first-order covariance), and the errors all of a frame's points share: the two
headings' and the displacement's (its white noise and its scale error). The shared ones are handed to
the back end as G (k, 3, 5), the innovation of each point per unit error of [earlier heading, later
heading, displacement (3)], by finite differences of the triangulation (the later heading turns the
prediction h = R(psi)^T (X - p) too), and their covariance (5, 5). Points under ``MIN_PARALLAX_RAD``
are not used: the first-order covariance of a point seen under less understates its depth error
(docs/ar-slam.md). The shared errors also bias the points: a point's depth is a nonlinear function
of the headings and the displacement, so their noise moves it one way on average (at 20-25 m about
5 cm short, 3.5 cm up for the camera 50 degrees down, from the headings' noise). That second-order
bias, tr(Hessian cov) / 2, is taken out of each point (``shared_bias``); the pixels' own is negligible
(under a millimetre) and the displacement's none.

Each frame's pixels and heading serve two pairs, as the later frame and then as the earlier one, so
two points of the same track ``span_s`` apart share an error the filter does not track. Their
variances are taken ``USES`` times, so that the two uses together count no more than once
(conservative: the two pairs' correlation is below one). Pure."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from bus.sensors.camera3d import PAPER_K, Camera3dSpec
from bus.sensors.camera3d import look as camera_rotation
from vehicle.vision.triangulation import camera_matrices, in_second_camera, triangulate, triangulated_points

MIN_PARALLAX_RAD = np.deg2rad(2.0)
USES = 2.0  # pairs each frame serves: as the later frame, then as the earlier one
SHARED_STEP = np.array([1e-4, 1e-4, 1e-3, 1e-3, 1e-3])  # rad, rad, m, m, m: the finite differences' steps


class FramePoints(NamedTuple):
    """A frame's usable points: z (k, 3) m in the later camera's frame, their covariances from the
    pixels' noise (k, 3, 3) m^2, what they share (G (k, 3, 5) and its covariance (5, 5), the back
    end's ``common``; None without points) and each point's track id (k,)."""

    z: np.ndarray
    cov: np.ndarray
    shared: tuple[np.ndarray, np.ndarray] | None
    tracks: np.ndarray


NO_POINTS = FramePoints(np.zeros((0, 3)), np.zeros((0, 3, 3)), None, np.zeros(0, dtype=np.int64))


@dataclass
class Frame:
    """A camera frame as received: stamp, the attitude sensor's heading, the inertial displacement
    since the frame ``span_s`` earlier (3,) m (``span_s`` 0: none), and each track's pixel."""

    stamp_us: int
    heading_rad: float
    displacement_m: np.ndarray
    span_s: float
    pixels: dict[int, tuple[float, float]] = field(default_factory=dict)

    @property
    def earlier_us(self) -> int:
        """The stamp of the frame this one is triangulated with (-1: none)."""
        return self.stamp_us - round(self.span_s * 1e6) if self.span_s else -1


def frame_points(
    earlier: Frame, later: Frame, spec: Camera3dSpec, uses: float = USES, debiased: bool = True
) -> FramePoints:
    """The points both frames track (module docstring), each frame's pixels and heading counted
    ``uses`` times, ``debiased`` of what the shared errors bias (``shared_bias``; False: the paper's
    triangulation as it comes); NO_POINTS when none is usable."""
    tracks = sorted(set(later.pixels) & set(earlier.pixels))
    if not tracks:
        return NO_POINTS
    uv1 = np.array([earlier.pixels[i] for i in tracks])
    uv2 = np.array([later.pixels[i] for i in tracks])
    inputs = np.r_[earlier.heading_rad, later.heading_rad, later.displacement_m]
    pitch = np.deg2rad(spec.pitch_deg)
    z, R_z, keep = triangulated(uv1, uv2, inputs, pitch, spec.pixel_sigma_px * np.sqrt(uses))
    if not keep.any():
        return NO_POINTS
    z, R_z, uv1, uv2, tracks = z[keep], R_z[keep], uv1[keep], uv2[keep], np.array(tracks)[keep]
    G = np.empty((len(z), 3, len(inputs)))
    for k in range(len(inputs)):  # the innovation's change per unit error of each input
        step = np.zeros(len(inputs))
        step[k] = SHARED_STEP[k]
        G[:, :, k] = innovation_change(uv1, uv2, inputs, step, pitch, z) / step[k]
    if debiased:
        z = z - shared_bias(uv1, uv2, inputs, pitch, shared_covariance(later.displacement_m, spec, 1.0), z)
    return FramePoints(z, R_z, (G, shared_covariance(later.displacement_m, spec, uses)), tracks)


def shared_bias(
    uv1: np.ndarray, uv2: np.ndarray, inputs: np.ndarray, pitch_rad: float, spread: np.ndarray, z: np.ndarray
) -> np.ndarray:
    """The second-order bias (k, 3) m of the innovations of the points ``z`` (k, 3) that the headings'
    errors cause (``inputs`` [earlier heading, later heading, displacement (3)], ``spread`` their
    covariance (5, 5)): E[e(d)] ~ tr(Hessian spread) / 2, e(d) the innovation's change for a heading
    error d (the later heading turns the prediction too, as in G), by the unscented transform's four
    symmetric sigma points of the two independent headings (weights 1 / 4: exact to second order).
    The displacement has none: the linear triangulation's points move linearly with it."""
    total = np.zeros_like(z)
    for k in (0, 1):
        for sign in (1.0, -1.0):
            step = np.zeros(len(inputs))
            step[k] = sign * np.sqrt(2.0 * spread[k, k])
            total += innovation_change(uv1, uv2, inputs, step, pitch_rad, z)
    return total / 4.0


def innovation_change(
    uv1: np.ndarray, uv2: np.ndarray, inputs: np.ndarray, step: np.ndarray, pitch_rad: float, z: np.ndarray
) -> np.ndarray:
    """How the innovations of the points ``z`` (k, 3) change (k, 3) m when the inputs [earlier heading,
    later heading, displacement (3)] change by ``step`` (5,): the points triangulated again, and where
    the later heading changes, the prediction h = R(psi)^T (X - p), with X - p = R(psi) z, turned too."""
    moved = moved_points(uv1, uv2, inputs + step, pitch_rad)
    if not step[1]:
        return moved - z
    turn = camera_rotation(inputs[1] + step[1], pitch_rad).T @ camera_rotation(inputs[1], pitch_rad)
    return moved - z @ turn.T


def shared_covariance(displacement_m: np.ndarray, spec: Camera3dSpec, uses: float = USES) -> np.ndarray:
    """The covariance (5, 5) of [earlier heading, later heading, displacement (3)]: each heading's
    noise (counted ``uses`` times: module docstring), the displacement's white noise per axis and its
    scale error along it (drawn for each frame: used once)."""
    out = np.zeros((5, 5))
    out[0, 0] = out[1, 1] = uses * spec.heading_sigma_rad**2
    out[2:, 2:] = spec.baseline_sigma_m**2 * np.eye(3) + spec.baseline_scale_sigma**2 * np.outer(
        displacement_m, displacement_m
    )
    return out


def triangulated(
    uv1: np.ndarray, uv2: np.ndarray, inputs: np.ndarray, pitch_rad: float, sigma_px: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (k, 3) m in the later camera's frame, their pixel covariances (k, 3, 3) and which are
    usable (k,) (in front of both cameras, parallax >= MIN_PARALLAX_RAD), from the pixels (k, 2) of the
    earlier and later frames and ``inputs`` [earlier heading, later heading, displacement (3)]."""
    R_rel, L = _relative_pose(inputs, pitch_rad)
    out = triangulate(*camera_matrices(PAPER_K, R_rel, L), uv1, uv2, sigma_px=sigma_px)
    z, cov = in_second_camera(R_rel, L, out.points, out.covariances)
    return z, cov, out.usable & (out.parallax_rad >= MIN_PARALLAX_RAD)


def moved_points(uv1: np.ndarray, uv2: np.ndarray, inputs: np.ndarray, pitch_rad: float) -> np.ndarray:
    """The points (k, 3) of :func:`triangulated` alone (the same values), for its finite differences."""
    R_rel, L = _relative_pose(inputs, pitch_rad)
    return triangulated_points(*camera_matrices(PAPER_K, R_rel, L), uv1, uv2) @ R_rel.T + L


def _relative_pose(inputs: np.ndarray, pitch_rad: float) -> tuple[np.ndarray, np.ndarray]:
    """Camera 1 -> camera 2 (X2 = R_rel X1 + L) from [earlier heading, later heading, displacement (3)]."""
    R1 = camera_rotation(inputs[0], pitch_rad)
    R2 = camera_rotation(inputs[1], pitch_rad)
    return R2.T @ R1, -R2.T @ inputs[2:]
