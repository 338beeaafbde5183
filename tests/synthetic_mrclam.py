"""A synthetic MRCLAM-like data set with known noise (tests only): robots driving smooth curves in a
room with surveyed landmarks, Vicon truth at 100 Hz, odometry at ~67 Hz that the robot follows
``lag_s`` later with white noise of known sigma (and heading noise growing with the turns by
``turn_sigma`` rad/sqrt(rad)), and range-bearing sightings with known sigma. Optionally the wheels'
scales are off (the robot moves at (1 + ``odom_scale``) times the speed and yaw rate the odometry
reports) and the range error grows with the range (``range_sigma_per_m``, white) and persists (a
Gauss-Markov error per robot and landmark, ``range_correlated_per_m`` of the range, correlation time
``range_correlation_s``), and the camera's range scale may be off (it reads every range
(1 + ``range_scale``) times as long)."""

from __future__ import annotations

import numpy as np

from bus.config import build_config
from sim.mrclam import MrclamData, RobotLog

LANDMARKS = np.array(
    [
        [6 + i, x, y, 0.001, 0.001]
        for i, (x, y) in enumerate([(-4, -3), (-4, 0), (-4, 3), (0, -3.5), (0, 3.5), (4, -3), (4, 0), (4, 3)])
    ],
    dtype=float,
)


NOMINAL_SENSORS = {
    "odom_speed_sigma_mps": 0.05,
    "odom_yaw_rate_sigma_radps": 0.1,
    "range_sigma_m": 0.1,
    "bearing_sigma_rad": 0.02,
    "prior_sigma_m": 0.05,
    "prior_heading_sigma_rad": 0.02,
}
PERSISTING_SENSORS = {
    "range_correlated_sigma_per_m": 0.04,
    "range_correlation_s": 3.0,
    "odom_scale_prior_sigma": 0.1,
    "bearing_correlated_fraction": 0.5,
    "bearing_correlation_s": 3.0,
}
PERSISTING_SIGHTING_SIGMAS = [float(np.hypot(0.015, 0.04)), 0.02]


def replay_config(estimator: str, seed: int, sensors: dict | None = None, robots: int = 1, **replay) -> object:
    """A replay of :func:`synthetic` on robots 1..``robots`` from 20 s, calibrated on [0, 20) s, with
    the data set's own white noise as the datasheet (the filter's nominal model) plus ``sensors``."""
    landmarks = [(int(i), float(x), float(y)) for i, x, y in LANDMARKS[:, :3]] if estimator == "known-map" else []
    return build_config(
        {
            "world": {"vehicles": robots, "seed": seed},
            "clock": {"duration_s": 80.0, "tick_s": 0.02},
            "sensors": {**NOMINAL_SENSORS, **(sensors or {})},
            "vehicle": {"estimator": estimator, "cooperation": {"enabled": False}, "landmarks": landmarks},
            "replay": {
                "dataset": "synthetic",
                "robots": list(range(1, robots + 1)),
                "start_s": 20.0,
                "calibration_s": [0, 20],
                "odom_lag_s": 0.2,
                **replay,
            },
        }
    )


def with_persisting_errors(rng: np.random.Generator, robots: int = 1) -> MrclamData:
    """101 s of :func:`synthetic` whose wheels are 6 % and -8 % off and whose range and bearing errors
    persist (4 % of the range, half the bearing variance, 3 s; the white part PERSISTING_SIGHTING_SIGMAS)."""
    return synthetic(
        rng,
        robots=robots,
        duration_s=101.0,
        range_sigma=0.0,
        range_sigma_per_m=0.015,
        range_correlated_per_m=0.04,
        range_correlation_s=3.0,
        odom_scale=(0.06, -0.08),
        sighting_rate_hz=6.0,
        bearing_correlated_fraction=0.5,
        bearing_correlation_s=3.0,
    )


def synthetic(
    rng: np.random.Generator,
    *,
    robots: int = 2,
    duration_s: float = 200.0,
    lag_s: float = 0.2,
    speed_sigma: float = 0.05,
    rate_sigma: float = 0.1,
    range_sigma: float = 0.1,
    bearing_sigma: float = 0.02,
    sighting_rate_hz: float = 3.0,
    turn_sigma: float = 0.0,
    odom_scale: tuple[float, float] = (0.0, 0.0),
    range_sigma_per_m: float = 0.0,
    range_correlated_per_m: float = 0.0,
    range_correlation_s: float = 5.0,
    robot_sighting_rate_hz: float = 0.0,
    camera_latency_s: float = 0.0,
    bearing_correlated_fraction: float = 0.0,
    bearing_correlation_s: float = 5.0,
    range_scale: float = 0.0,
) -> MrclamData:
    logs, poses = {}, {}
    for robot in range(1, robots + 1):
        fine = np.arange(0.0, duration_s, 0.002)
        command_t = np.arange(0.0, duration_s, 0.015)
        phase = rng.uniform(0, 2 * np.pi)
        commands = np.column_stack(
            [0.2 + 0.1 * np.sin(0.05 * command_t + phase), 0.3 * np.sin(0.11 * command_t + phase)]
        )
        noisy = commands + rng.normal(0.0, [speed_sigma, rate_sigma], commands.shape)
        # heading variance turn_sigma^2 per radian turned: over a 0.015 s hold, (sigma 0.015)^2 = turn^2 |w| 0.015
        if turn_sigma:
            noisy[:, 1] += turn_sigma * np.sqrt(np.abs(commands[:, 1]) / 0.015) * rng.standard_normal(len(commands))
        # the robot follows the (noisy) command lag_s later: the odometry reports the command without that noise
        held = noisy[np.clip(np.searchsorted(command_t, fine - lag_s, side="right") - 1, 0, None)] * (
            1.0 + np.asarray(odom_scale)
        )
        start = [rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-np.pi, np.pi)]
        # Euler steps of 2 ms, summed in the loop's order: pose[k] = pose[k - 1] + step(held[k - 1])
        heading = np.cumsum(np.concatenate([[start[2]], held[:-1, 1] * 0.002]))
        travel = held[:-1, 0] * 0.002
        pose = np.column_stack(
            [
                np.cumsum(np.concatenate([[start[0]], travel * np.cos(heading[:-1])])),
                np.cumsum(np.concatenate([[start[1]], travel * np.sin(heading[:-1])])),
                heading,
            ]
        )
        pose[:, 2] = (pose[:, 2] + np.pi) % (2 * np.pi) - np.pi
        truth = np.column_stack([fine, pose])[::5]
        sightings, persisting = [], {}  # landmark -> (time s, relative range error)
        bearing_persisting = {}  # landmark -> (time s, bearing error rad)
        for t in np.sort(rng.uniform(1.0, duration_s, int(sighting_rate_hz * duration_s))):
            k = int(t / 0.002)
            x, y, th = pose[k]
            d = LANDMARKS[:, 1:3] - [x, y]
            bearing = (np.arctan2(d[:, 1], d[:, 0]) - th + np.pi) % (2 * np.pi) - np.pi
            seen = np.flatnonzero(np.abs(bearing) < 0.5)
            if len(seen):
                j = rng.choice(seen)
                true_range = np.hypot(*d[j])
                noise = rng.normal(0, range_sigma)
                if range_sigma_per_m or range_correlated_per_m:  # (no draws otherwise: other tests' data unchanged)
                    before, error = persisting.get(j, (fine[k], rng.normal(0.0, range_correlated_per_m)))
                    phi = np.exp(-(fine[k] - before) / range_correlation_s)
                    error = phi * error + range_correlated_per_m * np.sqrt(1.0 - phi * phi) * rng.standard_normal()
                    persisting[j] = (fine[k], error)
                    noise += true_range * (error + rng.normal(0.0, range_sigma_per_m))
                if bearing_correlated_fraction:  # a Gauss-Markov part and a white part (no draws otherwise)
                    sigma = bearing_sigma * np.sqrt(bearing_correlated_fraction)
                    before, error = bearing_persisting.get(j, (fine[k], rng.normal(0.0, sigma)))
                    phi = np.exp(-(fine[k] - before) / bearing_correlation_s)
                    error = phi * error + sigma * np.sqrt(1.0 - phi * phi) * rng.standard_normal()
                    bearing_persisting[j] = (fine[k], error)
                    bearing_noise = error + rng.normal(0, bearing_sigma * np.sqrt(1.0 - bearing_correlated_fraction))
                else:
                    bearing_noise = rng.normal(0, bearing_sigma)
                sightings.append(
                    [
                        fine[k] + camera_latency_s,
                        LANDMARKS[j, 0],
                        true_range * (1.0 + range_scale) + noise,
                        bearing[j] + bearing_noise,
                    ]
                )  # stamped when read
        logs[robot] = RobotLog(
            robot, truth, np.column_stack([command_t, commands]), np.array(sightings).reshape(-1, 4), 0
        )
        poses[robot] = pose
    if robot_sighting_rate_hz:  # drawn after everything else: the rest of the data is as without them
        for robot, log in logs.items():
            seen = _robot_sightings(rng, poses, robot, duration_s, robot_sighting_rate_hz, range_sigma, bearing_sigma)
            both = np.vstack([log.sightings, seen])
            logs[robot] = RobotLog(robot, log.groundtruth, log.odometry, both[np.argsort(both[:, 0], kind="stable")], 0)
    return MrclamData(logs, LANDMARKS, 0.0)


def _robot_sightings(
    rng: np.random.Generator,
    poses: dict[int, np.ndarray],
    robot: int,
    duration_s: float,
    rate_hz: float,
    range_sigma: float,
    bearing_sigma: float,
) -> np.ndarray:
    """Rows [t, subject, range, bearing] of ``robot`` seeing the other robots (subjects 1-5) within
    0.5 rad of its heading, white noise, at ``rate_hz`` attempts a second."""
    rows = []
    for t in np.sort(rng.uniform(1.0, duration_s, int(rate_hz * duration_s))):
        k = int(t / 0.002)
        x, y, th = poses[robot][k]
        for other, pose in poses.items():
            dx, dy = pose[k, 0] - x, pose[k, 1] - y
            bearing = (np.arctan2(dy, dx) - th + np.pi) % (2 * np.pi) - np.pi
            if other != robot and abs(bearing) < 0.5:
                rows.append(
                    [
                        k * 0.002,
                        other,
                        np.hypot(dx, dy) + rng.normal(0, range_sigma),
                        bearing + rng.normal(0, bearing_sigma),
                    ]
                )
    return np.array(rows).reshape(-1, 4)
