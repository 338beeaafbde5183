"""What a flat-ground map sees: a landmark's pixel in one frame turned into a point by intersecting its
ray with a plane a known height below the camera (the camera's height over the ground beneath it, an
altimeter's reading), as a down-looking vehicle with a 2-D map places what it sees. Over flat ground
with the landmarks on it this is exact up to the pixels' noise; over relief, and for landmarks that
stand above the ground, it is wrong by what the plane misses, which nothing in the model knows.
The AR-EKF-SLAM paper triangulates instead (vehicle.vision.triangulation); experiments.ar_slam3d
flies both on the same flights (``fly(..., flat_ground=True)``). Pure."""

from __future__ import annotations

import numpy as np

from sim.pinhole import Pinhole

HEIGHT_SIGMA_M = 0.5  # what the model is told of the plane's height: an altimeter's noise and the height's wander
MIN_DOWN = 0.02  # a ray must descend at least this much per unit length to meet the plane ahead


def flat_ground_points(
    camera: Pinhole,
    landmarks: np.ndarray,
    C: np.ndarray,
    R_wc: np.ndarray,
    height_m: float,
    see_m: float,
    rng: np.random.Generator,
    sigma_px: float = 1.0,
    height_sigma_m: float = HEIGHT_SIGMA_M,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The landmarks (m, 3) the camera at C (3,) with axes R_wc (3, 3) sees (in front, in the frame,
    nearer than ``see_m``), each placed where its pixel's ray (``sigma_px`` of noise per coordinate)
    meets the plane ``height_m`` below C (known to ``height_sigma_m``): points (k, 3) in the camera's
    frame, their covariances (k, 3, 3) from the pixels' noise and the height's, and the landmarks'
    indices (k,)."""
    uv, depth = camera.project(R_wc, C, landmarks)
    seen = camera.in_view(uv, depth, see_m)
    index = np.flatnonzero(seen)
    noisy = uv[seen] + rng.normal(0.0, sigma_px, (len(index), 2))
    K_inv = np.linalg.inv(camera.K)
    rays = np.column_stack([noisy, np.ones(len(index))]) @ K_inv.T  # camera frame, unit depth
    down = rays @ R_wc.T[:, 2]  # the rays' vertical component in the fixed frame
    ahead = down < -MIN_DOWN * np.linalg.norm(rays, axis=1)
    rays, down, index = rays[ahead], down[ahead], index[ahead]
    s = -height_m / down
    points = s[:, None] * rays  # X_c = s r, with (R_wc X_c)_z = -height_m
    near = np.linalg.norm(points, axis=1) < see_m
    points, rays, down, s, index = points[near], rays[near], down[near], s[near], index[near]
    # d X_c / d(u, v) = s d r + r d s, with d r = K^-1 e_(u, v) and d s = height_m (R_wc d r)_z / down^2
    dr = K_inv[:, :2]  # (3, 2): d r / d(u, v)
    ds = height_m * (R_wc[2] @ dr)[None, :] / down[:, None] ** 2  # (k, 2)
    J = s[:, None, None] * dr[None] + rays[:, :, None] * ds[:, None, :]
    along = points / height_m  # d X_c / d height_m
    covariances = sigma_px**2 * np.einsum("nia,nja->nij", J, J) + height_sigma_m**2 * np.einsum(
        "ni,nj->nij", along, along
    )
    return points, covariances, index
