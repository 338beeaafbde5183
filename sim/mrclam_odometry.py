"""The odometry part of an MRCLAM data set's datasheet (sim.mrclam_calibration), calibrated against
its ground truth on an interval. Pure: data in, numbers out.

- Odometry lag: MRCLAM's odometry is the commanded speed and yaw rate; the robot follows a command
  some 0.1-0.3 s later. The lag (one for the swarm, on a ``LAG_STEP_S`` grid up to ``MAX_LAG_S``) is
  the one that best matches the commands to the speed and yaw rate of the Vicon track; the replay
  stamps each command at the time it takes effect, as a sensor-to-sensor time offset is calibrated.
- Odometry (commanded speed and yaw rate, lag removed, held between samples): integrated over windows
  from the true pose, against the true pose at the window's end. The windows are as long as the
  odometry has to carry a robot alone between landmark sightings, typically (``blind_stretch``: the
  gaps' length-weighted mean, 13-15 s on data set 6): the error does not grow as a random walk, its
  variance per second is 1.5-1.8 times larger over 20 s windows than over 5 s ones, so a datasheet
  fitted on short windows would have the filter sure of itself exactly where it drives blind. The
  error grows with
  time and with the motion: a window's squared along-track error ~ a T + b d (T its length, d the
  distance travelled) and its squared heading error ~ c T + e r (r the angle turned), fitted by
  non-negative least squares over the windows (the odometry motion model of Thrun et al.,
  Probabilistic Robotics, 5.4). A filter that takes a held sample's noise as white with sigma s has
  a motion error of variance s^2 * (sample period) per second, so the time terms give the speed and
  yaw-rate sigmas; sqrt(b) and sqrt(e) are the travel and turn sigmas (m/sqrt(m), rad/sqrt(rad)).
  On data set 6 the turn term carries most of the heading error: windows that turn more than
  0.4 rad err three times as much as windows that hardly turn.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from bus.angles import wrap_angle
from sim.mrclam import MrclamData, RobotLog, delayed, pose_at

LAG_STEP_S, MAX_LAG_S = 0.01, 0.5
RATE_STEP_S = 0.02  # Vicon differentiated over this
WINDOW_S = 5.0  # the shortest odometry window (blind_stretch sets the one used)
MOVING_MPS = 0.01  # windows where the robot is commanded to stand still say nothing about its wheels


@dataclass(frozen=True)
class OdometryFit:
    """The odometry's lag (s), its datasheet sigmas and how many windows they were measured on."""

    lag_s: float
    speed_sigma_mps: float
    yaw_rate_sigma_radps: float
    travel_sigma_m: float
    turn_sigma_rad: float
    windows: int


def fit_odometry(
    data: MrclamData, interval_s: tuple[float, float], robots: tuple[int, ...], landmarks: list[int]
) -> OdometryFit:
    """The odometry lag and noise of ``robots`` on ``interval_s`` (module docstring); ``landmarks``:
    the subjects that are landmarks (their sightings end a blind stretch). With no moving window to
    fit on, the sigmas are 0: check ``windows``."""
    t0, t1 = interval_s
    lags = np.arange(0.0, MAX_LAG_S + 1e-9, LAG_STEP_S)
    lag = float(lags[np.argmin(sum(lag_mismatch(data.robots[r], t0, t1, lags) for r in robots))])
    window = blind_stretch(data, interval_s, robots, landmarks)
    fitted = [odometry_errors(delayed(data.robots[r], lag), t0, t1, window) for r in robots]
    errors, extents = np.vstack([w[0] for w in fitted]), np.vstack([w[1] for w in fitted])
    if len(errors) == 0:
        return OdometryFit(lag, 0.0, 0.0, 0.0, 0.0, 0)
    period = float(np.mean([np.median(np.diff(data.robots[r].odometry[:, 0])) for r in robots]))
    along_per_s, along_per_m, heading_per_s, heading_per_rad = growth_rates(errors, extents)
    return OdometryFit(
        lag,
        float(np.sqrt(along_per_s / period)),
        float(np.sqrt(heading_per_s / period)),
        float(np.sqrt(along_per_m)),
        float(np.sqrt(heading_per_rad)),
        len(errors),
    )


def odometry_errors(log: RobotLog, t0: float, t1: float, window_s: float = WINDOW_S) -> tuple[np.ndarray, np.ndarray]:
    """Along-track (m) and heading (rad) error (k, 2) of the held odometry integrated over
    consecutive windows in [t0, t1) from the true pose, against the true pose, and each window's
    [length s, distance travelled m, angle turned rad] (k, 3) by the odometry; moving windows only.
    The along-track error is the speed's alone: the commanded speeds are integrated along the true
    track (Vicon's heading at each hold), and the error is the distance from the true end (the
    heading's error, which bends an integrated track further off the longer the window, is the yaw
    rate's, measured apart)."""
    od, out, extents = log.odometry, [], []
    for start in np.arange(t0, t1 - window_s, window_s):
        before = np.flatnonzero(od[:, 0] <= start)
        inside = np.flatnonzero((od[:, 0] > start) & (od[:, 0] < start + window_s))
        if not len(before):
            continue
        rows = od[np.concatenate([before[-1:], inside])]
        times = np.append(np.maximum(rows[:, 0], start), start + window_s)
        if np.max(np.abs(rows[:, 1])) < MOVING_MPS:
            continue
        ends = pose_at(log.groundtruth, np.array([start, start + window_s]))
        if not np.all(np.isfinite(ends)):
            continue
        dt = np.diff(times)
        heading = ends[0, 2] + np.sum(rows[:, 2] * dt)
        track = pose_at(log.groundtruth, 0.5 * (times[:-1] + times[1:]))[:, 2]
        if not np.all(np.isfinite(track)):
            continue
        step = rows[:, 1] * dt
        x = ends[0, 0] + np.sum(step * np.cos(track))
        y = ends[0, 1] + np.sum(step * np.sin(track))
        out.append([np.hypot(x - ends[1, 0], y - ends[1, 1]), wrap_angle(heading - ends[1, 2])])
        extents.append([window_s, np.sum(np.abs(step)), np.sum(np.abs(rows[:, 2]) * dt)])
    return np.array(out).reshape(-1, 2), np.array(extents).reshape(-1, 3)


def growth_rates(errors: np.ndarray, extents: np.ndarray) -> tuple[float, float, float, float]:
    """Non-negative (a, b, c, e) with along-track error^2 ~ a T + b d and heading error^2 ~ c T + e r
    over windows of errors (k, 2) [m, rad] and extents (k, 3) [T s, d m, r rad]: variances per
    second (m^2/s, rad^2/s), per metre travelled (m^2/m) and per radian turned (rad^2/rad)."""
    (a, b), _ = nnls(extents[:, [0, 1]], errors[:, 0] ** 2)
    (c, e), _ = nnls(extents[:, [0, 2]], errors[:, 1] ** 2)
    return float(a), float(b), float(c), float(e)


def lag_mismatch(log: RobotLog, t0: float, t1: float, lags_s: np.ndarray) -> np.ndarray:
    """Mean squared difference (len(lags),) between the held commands, delayed by each lag, and the
    Vicon track's speed (m/s) and yaw rate (rad/s), each divided by its variance, over [t0, t1)."""
    t = np.arange(t0, t1, RATE_STEP_S)
    pose = pose_at(log.groundtruth, t)
    speed = np.hypot(*np.gradient(pose[:, :2], RATE_STEP_S, axis=0).T)
    rate = np.gradient(np.unwrap(np.nan_to_num(pose[:, 2])), RATE_STEP_S)
    ok = np.isfinite(speed) & np.isfinite(pose[:, 2])
    od = log.odometry
    out = []
    for lag in lags_s:
        held = od[np.clip(np.searchsorted(od[:, 0], t - lag, side="right") - 1, 0, len(od) - 1)]
        out.append(
            np.mean((held[ok, 1] - speed[ok]) ** 2) / max(np.var(speed[ok]), 1e-9)
            + np.mean((held[ok, 2] - rate[ok]) ** 2) / max(np.var(rate[ok]), 1e-9)
        )
    return np.array(out)


def blind_stretch(
    data: MrclamData, interval_s: tuple[float, float], robots: tuple[int, ...], landmarks: list[int]
) -> float:
    """How long (s) the odometry has to carry a robot alone, typically: the mean length of the gaps
    between its sightings of ``landmarks`` (subjects) on ``interval_s``, weighted by their length (the
    gap a moment of the interval lies in, on average), pooled over ``robots``; at least WINDOW_S."""
    t0, t1 = interval_s
    gaps = []
    for robot in robots:
        t = data.robots[robot].sightings
        t = t[(t[:, 0] >= t0) & (t[:, 0] < t1) & np.isin(t[:, 1], landmarks), 0]
        gaps.append(np.diff(np.concatenate([[t0], np.sort(t), [t1]])))
    g = np.concatenate(gaps)
    return max(WINDOW_S, float(np.sum(g**2) / max(np.sum(g), 1e-9)))
