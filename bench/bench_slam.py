"""Vision EKF-SLAM costs:

- the core (vehicle/models/landmarks.py): one range-bearing update against the size of the map, the
  in-place update (five columns for the gain, two rank-1 BLAS updates on P's own memory) side by
  side with the textbook dense one that builds new n x n arrays per update (target: <= 5 ms at
  900 landmarks);
- the front end: keypoints, descriptors and range-bearing per frame, SIFT and ORB, 80 and 320 px;
- camera vehicles running ekf-slam in realtime at 50 Hz (5 vehicles): cycle p99 and overruns.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from bench.common import Row, per_call_us
from vehicle.models.landmarks import observe, update

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
    H[:, :3], H[:, 3 + 2 * j : 5 + 2 * j] = H_pose, H_landmark
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    return x + K @ (z - predicted), P - K @ (H @ P)


CAMERA_SCENARIO = """
name = "camera"
[sensors]
camera_rate_hz = 10
[vehicle]
estimator = "ekf-slam"
"""


def front_end_rows() -> list[Row]:
    """Detector + descriptors + range-bearing per frame, on frames of the procedural terrain."""
    from sim.camera import camera_frame
    from sim.terrain import procedural_terrain
    from vehicle.vision import features

    terrain = procedural_terrain(np.random.default_rng(1), size_px=1024)
    rng = np.random.default_rng(2)
    rows = []
    for size in (80, 320):
        frames = [
            camera_frame(terrain, np.array([x, 0.5 * x, 0.3 * x]), rng, size_px=size) for x in np.linspace(-20, 20, 8)
        ]
        for kind in ("sift", "orb"):
            detector = features.make_detector(kind)
            found = [len(features.detect(f, detector).responses) for f in frames]
            state = {"k": 0}

            def one_frame() -> None:
                frame = frames[state["k"] % len(frames)]
                state["k"] += 1
                f = features.detect(frame, detector)
                features.range_bearing(f.points_px, size, 0.1)

            us = per_call_us(one_frame, calls=16 if size == 320 else 64, repeats=3)
            rows.append(
                Row(
                    "slam",
                    f"front end, {kind.upper()}, {size} x {size} px",
                    "per frame",
                    round(us, 1),
                    "us",
                    "-",
                    None,
                    {"keypoints_mean": round(float(np.mean(found)), 1)},
                )
            )
    return rows


def camera_vehicle_rows(quick: bool) -> list[Row]:
    """5 camera vehicles with ekf-slam in realtime at 50 Hz (GNSS on): loop cycle p99 and overruns."""
    from bench.bench_swarm import run_case

    with tempfile.TemporaryDirectory() as tmp:
        scenario = Path(tmp) / "camera.toml"
        scenario.write_text(CAMERA_SCENARIO)
        print("  slam: realtime, 5 camera vehicles ...", flush=True)
        r = run_case(5, "realtime", 10 if quick else 20, Path(tmp), scenario)
    case = "realtime 50 Hz, 5 camera vehicles (ekf-slam)"
    return [
        Row("slam", case, "loop overruns", round(100 * r["overrun_rate"], 2), "%", "< 1%", r["overrun_rate"] < 0.01, r),
        Row("slam", case, "cycle p99", round(r["cycle_p99_us"] / 1000, 2), "ms", "-", None),
    ]


def run(quick: bool = False) -> list[Row]:
    rng = np.random.default_rng(0)
    rows = front_end_rows() + camera_vehicle_rows(quick)
    for landmarks in (100, 900) if quick else (100, 300, 900, 2000):
        x, P = _map(landmarks, rng)
        j = landmarks // 2
        z = observe(x, 3, j)[0] + np.array([0.05, 0.005])
        calls = max(3, 20_000 // landmarks)
        in_place = per_call_us(lambda: update(x, P, 3, j, z, R, gate=1e9), calls=calls, repeats=3)
        dense = per_call_us(lambda: _dense_update(x, P, j, z), calls=max(2, calls // 4), repeats=3)
        target = f"<= {TARGET_US:g} us" if landmarks == 900 else "-"
        met = in_place <= TARGET_US if landmarks == 900 else None
        rows.append(
            Row(
                "slam",
                f"EKF-SLAM update, {landmarks} landmarks (n = {3 + 2 * landmarks})",
                "in place per update",
                round(in_place, 1),
                "us",
                target,
                met,
                {"dense_us": round(dense, 1), "speedup": round(dense / in_place, 1)},
            )
        )
        rows.append(
            Row(
                "slam",
                f"EKF-SLAM update, {landmarks} landmarks (n = {3 + 2 * landmarks})",
                "textbook dense per update",
                round(dense, 1),
                "us",
                "-",
                None,
            )
        )
    return rows
