"""The AR-EKF-SLAM paper's 3-D experiment on its back end (vehicle.estimators.ar_slam3d): a camera
flying over landmarks on terrain with relief, each frame's landmarks triangulated from the previous
frame and this one (vehicle.vision.triangulation: the paper's K, 1 px noise), fused by the 6 + 3n EKF
with the adaptive range, a fixed 25 m range, or no range (full EKF-SLAM). Pure; seeded.

The flight: 10 frames a second at about 5 m/s (the paper: 1,605 frames over about 820 m), 15 m over
the ground, climbing, descending and turning gently, its velocity also driven by white noise; the
camera looks ahead, 30 degrees below the horizon. What is given, not estimated (as in the paper):
each frame's rotation and the baseline between two frames (visual odometry's R and, for the scale,
the metric length of L). Points are the landmarks seen in both frames (in the image, in front, under
60 m); triangulations the module refuses (too little parallax) are not observed.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bus.config import ArSlamConfig
from bus.sensors.camera3d import PAPER_K, look
from experiments.flat_ground import flat_ground_points
from sim.pinhole import PAPER_SIZE, Pinhole
from sim.relief import rolling_hills as ground
from vehicle.estimators.ar_slam3d import ArSlam3d
from vehicle.models import slam3d
from vehicle.vision.triangulation import camera_matrices, covariance_at, in_second_camera, triangulate

RATE_HZ, SPEED_MPS, HEIGHT_M, PITCH_RAD, SEE_M = 10.0, 5.0, 15.0, np.deg2rad(30.0), 60.0
OMEGA_VAR = 4e-4  # the truth's white velocity increments per frame, m^2/s^2
FIT_SEEDS, FIT_HORIZON_FRAMES = range(100, 110), 10  # flights the filter's motion model is fitted on (never scored)
TOWN_X_M, TOWN_DENSITY = (250.0, 450.0), 4.0
MODES = {
    "adaptive": dict(adaptive=True),
    "fixed-25": dict(adaptive=False),
    "full": dict(adaptive=False, spec=ArSlamConfig(r0_m=10_000.0, r_max_m=10_000.0)),
}


@dataclass(frozen=True)
class Track:
    """Per frame: time s, true position (3,), estimated position (3,), its covariance (3, 3), the
    range R m, landmarks in the state, landmarks mapped so far (in the state or retired), the frame's
    wall time ms (prediction + frame), the vehicle's whole error [position, velocity] (6,) with its
    covariance (6, 6), and the mean NEES (3 dof) of the landmarks in the state (NaN when they are not
    identified or there are none)."""

    t_s: np.ndarray
    truth: np.ndarray
    estimate: np.ndarray
    covariance: np.ndarray
    radius_m: np.ndarray
    landmarks: np.ndarray
    mapped: np.ndarray
    frame_ms: np.ndarray
    vehicle_error: np.ndarray
    vehicle_covariance: np.ndarray
    landmark_nees: np.ndarray

    def position_nees(self) -> np.ndarray:
        return nees(self.estimate - self.truth, self.covariance)

    def vehicle_nees(self) -> np.ndarray:
        """The NEES of the vehicle's whole state [p, v] (6 dof) per frame."""
        return nees(self.vehicle_error, self.vehicle_covariance)


def nees(errors: np.ndarray, covariances: np.ndarray) -> np.ndarray:
    """e_k^T P_k^-1 e_k of errors (k, d) and their covariances (k, d, d): (k,)."""
    return np.einsum("ni,nij,nj->n", errors, np.linalg.inv(covariances), errors)


def landmark_nees(slam: ArSlam3d, landmarks: np.ndarray) -> float:
    """Mean NEES (3 dof) of the state's landmarks against their true positions (m, 3), by id; NaN when
    the landmarks are not identified or the state has none."""
    if not len(slam.ids) or (slam.ids < 0).any():
        return float("nan")
    starts = [slam3d.HEAD + slam3d.POINT * j for j in range(len(slam.ids))]
    blocks = np.array([slam.P[a : a + slam3d.POINT, a : a + slam3d.POINT] for a in starts])
    return float(np.mean(nees(slam.landmarks() - landmarks[slam.ids], blocks)))


def world(seed: int, frames: int, town: bool = True, relief: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Landmarks (m, 3) along the flight (``town``: with the dense stretch), the camera's true positions
    (frames, 3) and rotations (frames, 3, 3). ``relief``: over the rolling hills, the landmarks 0-4 m
    above the ground; else over flat ground at height 0 with the landmarks on it."""
    rng = np.random.default_rng([seed, 3])
    under = ground if relief else flat
    positions, rotations = trajectory(rng, frames, lambda t: 0.35 * np.sin(t / 25.0), under, np.zeros(2))
    low, high = positions[:, :2].min(axis=0) - 60.0, positions[:, :2].max(axis=0) + 60.0
    count = int(np.prod(high - low) / 15.0)  # one landmark per 15 m^2 of ground
    xy = rng.uniform(low, high, (count, 2))
    town_low, town_high = np.array([TOWN_X_M[0], low[1]]), np.array([TOWN_X_M[1], high[1]])
    extra = int(np.prod(town_high - town_low) / 15.0 * (TOWN_DENSITY - 1.0)) if town else 0
    xy = np.vstack([xy, rng.uniform(town_low, town_high, (max(extra, 0), 2))])
    count = len(xy)
    above = rng.uniform(0.0, 4.0, count)
    landmarks = np.column_stack([xy, under(xy) + (above if relief else 0.0)])
    return landmarks, positions, rotations


def flat(xy: np.ndarray) -> np.ndarray:
    """Flat ground (m) at world points (..., 2): height 0."""
    return np.zeros(np.shape(xy)[:-1])


def trajectory(
    rng: np.random.Generator,
    frames: int,
    heading: Callable[[float], float],
    ground: Callable,
    start_xy: np.ndarray,
    pitch_rad: float = PITCH_RAD,
) -> tuple[np.ndarray, np.ndarray]:
    """The camera's true positions (frames, 3) and rotations (frames, 3, 3): from ``start_xy`` at
    SPEED_MPS, steering towards ``heading(t)`` rad and HEIGHT_M over ``ground`` (relief at (..., 2)),
    so climbing and descending with it, its velocity also driven by white noise (OMEGA_VAR); the camera
    looks along the velocity, ``pitch_rad`` below the horizon."""
    dt = 1.0 / RATE_HZ
    h0 = heading(0.0)
    p = np.array([*start_xy, HEIGHT_M + ground(np.asarray(start_xy))])
    v = SPEED_MPS * np.array([np.cos(h0), np.sin(h0), 0.0])
    positions, rotations = [], []
    for k in range(frames):
        t = k * dt
        climb = 0.3 * (HEIGHT_M + ground(p[:2]) - p[2])  # following the relief: climbing and descending
        wanted = np.array([SPEED_MPS * np.cos(heading(t)), SPEED_MPS * np.sin(heading(t)), climb])
        v = v + 0.05 * (wanted - v) + rng.normal(0.0, np.sqrt(OMEGA_VAR), 3)
        p = p + v * dt
        positions.append(p.copy())
        rotations.append(look(float(np.arctan2(v[1], v[0])), pitch_rad))
    return np.array(positions), np.array(rotations)


@functools.cache
def motion_noise() -> np.ndarray:
    """What the filter is told of the vehicle's motion: per axis of the fixed frame, the variance of
    the true velocity's change over ``FIT_HORIZON_FRAMES`` frames (the triangulation's baseline), per
    frame, on flights of their own (``FIT_SEEDS``) (3,) m^2/s^2. Following the relief adds to the
    velocity what is not white: its vertical part changes slowly, by more over a second than white
    noise of its per-frame variance would (docs/ar-slam.md)."""
    m = FIT_HORIZON_FRAMES
    velocities = [np.diff(world(seed, 1600)[1], axis=0) * RATE_HZ for seed in FIT_SEEDS]
    return np.concatenate([v[m:] - v[:-m] for v in velocities]).var(axis=0) / m


def observe(
    landmarks, C1, R1, C2, R2, rng: np.random.Generator, min_parallax_rad: float = 0.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Callable[[np.ndarray], np.ndarray]]:
    """The landmarks seen from both cameras, triangulated: points (k, 3) in camera 2, covariances
    (k, 3, 3), the landmarks' indices (k,), and the covariances the same triangulation gives any
    points (m, 3) in camera 2 (the back end's ``noise_at``)."""
    camera = Pinhole(PAPER_K, PAPER_SIZE)
    pixels, depths = zip(*(camera.project(R, C, landmarks) for C, R in ((C1, R1), (C2, R2))))
    seen = np.ones(len(landmarks), bool)
    for uv, d in zip(pixels, depths):
        seen &= camera.in_view(uv, d, SEE_M)
    R_rel, L = R2.T @ R1, R2.T @ (C1 - C2)  # camera 1 -> camera 2: X2 = R_rel X1 + L
    cameras = camera_matrices(PAPER_K, R_rel, L)
    noise_at = functools.partial(_noise_in_camera_2, cameras, R_rel, L)
    if not seen.any():
        return np.zeros((0, 3)), np.zeros((0, 3, 3)), np.zeros(0, np.int64), noise_at
    uv1, uv2 = (uv[seen] + rng.normal(0.0, 1.0, (seen.sum(), 2)) for uv in pixels)
    out = triangulate(*cameras, uv1, uv2)
    keep = out.usable & (out.parallax_rad >= min_parallax_rad)
    z, cov = in_second_camera(R_rel, L, out.points[keep], out.covariances[keep])
    return z, cov, np.flatnonzero(seen)[keep], noise_at


def on_flat_ground(
    landmarks: np.ndarray, C: np.ndarray, R_wc: np.ndarray, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray, np.ndarray, None]:
    """``observe``'s answer as a flat-ground map has it (experiments.flat_ground): the landmarks the
    camera at C sees, placed from its own pixels on a plane HEIGHT_M below it; no ``noise_at``."""
    z, R_z, seen = flat_ground_points(Pinhole(PAPER_K, PAPER_SIZE), landmarks, C, R_wc, HEIGHT_M, SEE_M, rng)
    return z, R_z, seen, None


def _noise_in_camera_2(cameras: tuple, R_rel: np.ndarray, L: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The triangulation's covariances (m, 3, 3) in camera 2 of points z (m, 3) in camera 2."""
    X1 = (z - L) @ R_rel
    return in_second_camera(R_rel, L, X1, covariance_at(*cameras, X1))[1]


def fly(
    seed: int,
    frames: int,
    mode: str,
    *,
    baseline_frames: int = 10,
    min_parallax_deg: float = 2.0,
    identified: bool = True,
    association: str = "nn",
    entry: str = "second",
    town: bool = True,
    noise: bool = True,
    on_frame: Callable[[int, ArSlam3d, float], None] | None = None,
    relief: bool = True,
    flat_ground: bool = False,
) -> Track:
    """One flight of ``frames`` frames with the back end in ``mode`` (MODES), each frame triangulated
    with the one ``baseline_frames`` before it; ``identified``: association by landmark id (the back
    end alone), else by ``association`` on the triangulated points; ``entry``: how points enter the map
    (vehicle.estimators.ar_slam3d); ``noise``: a landmark's sighting fused with the noise at its
    prediction (the back end's ``noise_at``; False: at its own pixels); ``on_frame(k, back end, frame
    ms)``: called after each frame (a recording), outside the frame's timing. ``relief``: over the
    hills, else flat ground (``world``). ``flat_ground``: each frame's landmarks placed from its own
    pixels on a plane HEIGHT_M below the camera (experiments.flat_ground: what a flat-ground map
    sees) instead of triangulated from two frames."""
    landmarks, positions, rotations = world(seed, frames + 1, town, relief)
    rng = np.random.default_rng([seed, 5])
    dt = 1.0 / RATE_HZ
    v0 = (positions[1] - positions[0]) / dt
    x0 = np.concatenate([positions[0] + rng.normal(0, 0.05, 3), v0 + rng.normal(0, 0.05, 3)])
    P0 = np.diag([0.05**2] * 3 + [0.05**2] * 3)
    slam = ArSlam3d(x0, P0, omega_var=motion_noise(), seed=seed, association=association, entry=entry, **MODES[mode])
    rows = []
    parallax = np.deg2rad(min_parallax_deg)
    for k in range(1, frames + 1):
        if flat_ground:
            z, R_z, seen, noise_at = on_flat_ground(landmarks, positions[k], rotations[k], rng)
        else:
            j = max(0, k - baseline_frames)
            z, R_z, seen, noise_at = observe(
                landmarks, positions[j], rotations[j], positions[k], rotations[k], rng, parallax
            )
        start = time.perf_counter()
        slam.predict(dt)
        slam.frame(z, R_z, rotations[k], seen if identified else None, noise_at=noise_at if noise else None)
        elapsed = (time.perf_counter() - start) * 1e3
        rows.append(track_row(slam, k, positions, elapsed, landmark_nees(slam, landmarks)))
        if on_frame is not None:
            on_frame(k, slam, elapsed)
    return Track(*(np.array(column) for column in zip(*rows)))


def track_row(slam: ArSlam3d, k: int, positions: np.ndarray, elapsed_ms: float, landmarks_nees: float) -> tuple:
    """Frame ``k``'s row of a Track (its fields in order) from the back end after the frame, the true
    positions (frames, 3), the frame's wall time and the landmarks' mean NEES."""
    dt = 1.0 / RATE_HZ
    velocity = (positions[k] - positions[k - 1]) / dt  # the truth's velocity over the frame (sim: p += v dt)
    head = slice(0, slam3d.HEAD)
    return (
        k * dt,
        positions[k],
        slam.x[:3].copy(),
        slam.P[:3, :3].copy(),
        slam.book.radius_m,
        (len(slam.x) - slam3d.HEAD) // slam3d.POINT,
        slam.book.added,
        elapsed_ms,
        slam.x[head] - np.concatenate([positions[k], velocity]),
        slam.P[head, head].copy(),
        landmarks_nees,
    )
