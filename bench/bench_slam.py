"""EKF-SLAM core (vehicle/ekf_slam_core.py): cost of one range-bearing update against the size of
the map, the in-place update (five columns for the gain, two rank-1 BLAS updates on P's own memory)
side by side with the textbook dense one that builds new n x n arrays per update.

Target (issue 12): <= 5 ms per update at 900 landmarks.
"""

from __future__ import annotations

import numpy as np

from bench.common import Row, per_call_us
from vehicle.ekf_slam_core import observe, update

TARGET_US = 5000.0
R = np.diag([0.1**2, 0.01**2])


def _map(landmarks: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A state with ``landmarks`` landmarks and an SPD covariance (diagonal plus rank 5: cheap to make)."""
    n = 3 + 2 * landmarks
    x = np.concatenate([[0.0, 0.0, 0.1], rng.uniform(-50, 50, size=2 * landmarks)])
    U = rng.normal(size=(n, 5)) * 0.1
    return x, np.diag(rng.uniform(0.01, 0.1, size=n)) + U @ U.T


def _dense_update(x: np.ndarray, P: np.ndarray, j: int, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The textbook EKF update with a full H (2, n): new x and new n x n P every time."""
    predicted, H_pose, H_landmark = observe(x, 3, j)
    H = np.zeros((2, len(x)))
    H[:, :3], H[:, 3 + 2 * j:5 + 2 * j] = H_pose, H_landmark
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - predicted), P - K @ (H @ P)


def run(quick: bool = False) -> list[Row]:
    rng = np.random.default_rng(0)
    rows = []
    for landmarks in ((100, 900) if quick else (100, 300, 900, 2000)):
        x, P = _map(landmarks, rng)
        j = landmarks // 2
        z = observe(x, 3, j)[0] + np.array([0.05, 0.005])
        calls = max(3, 20_000 // landmarks)
        in_place = per_call_us(lambda: update(x, P, 3, j, z, R, gate=1e9), calls=calls, repeats=3)
        dense = per_call_us(lambda: _dense_update(x, P, j, z), calls=max(2, calls // 4), repeats=3)
        target = f"<= {TARGET_US:g} us" if landmarks == 900 else "-"
        met = in_place <= TARGET_US if landmarks == 900 else None
        rows.append(Row("slam", f"EKF-SLAM update, {landmarks} landmarks (n = {3 + 2 * landmarks})",
                        "in place per update", round(in_place, 1), "us", target, met,
                        {"dense_us": round(dense, 1), "speedup": round(dense / in_place, 1)}))
        rows.append(Row("slam", f"EKF-SLAM update, {landmarks} landmarks (n = {3 + 2 * landmarks})",
                        "textbook dense per update", round(dense, 1), "us", "-", None))
    return rows
