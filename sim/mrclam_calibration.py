"""Noise datasheet of an MRCLAM data set, calibrated against its ground truth on an interval that is
then never scored (Leung et al., IJRR 2011). Pure: data in, numbers out.

- Sightings (camera range and bearing to landmarks): residuals against the range and bearing the
  Vicon pose and the surveyed landmark give; gross misreadings (beyond ``OUTLIER_SIGMAS`` robust
  sigmas: wrong barcode, occlusion) are counted, not folded into the sigma; the sigma is the RMS of
  the rest, bias included (the filter has no bias state).
- Odometry lag: MRCLAM's odometry is the commanded speed and yaw rate; the robot follows a command
  some 0.1-0.3 s later. The lag (one for the swarm, on a ``LAG_STEP_S`` grid up to ``MAX_LAG_S``) is
  the one that best matches the commands to the speed and yaw rate of the Vicon track; the replay
  stamps each command at the time it takes effect, as a sensor-to-sensor time offset is calibrated.
- Camera latency: a sighting is stamped when the image was read, some tens of milliseconds after it
  was taken; while the robot turns, that shows as a bearing error of yaw rate times latency, the
  same for every sighting of the turn. The latency (one for the swarm, on the ``LAG_STEP_S`` grid up
  to ``MAX_CAMERA_LATENCY_S``) is the one that minimises the robust RMS of the landmark bearings'
  residuals; every sighting statistic below is taken on the sightings restamped with it, and so is
  the replay (``replay.camera_latency_s``).
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
- Range error's growth and persistence: the camera reads a landmark's range from its size in the
  image, so the error grows with the range (a pixel of height error is a fixed fraction of the
  range): each robot's camera gets a relative range sigma, the robust RMS of error / true range
  (``sighting_sigmas``; 4.3 % on data set 6 at 1-2 m and at 4-5 m alike). And it persists: the relative
  errors of one robot's sightings of one landmark correlate as rho(lag) ~ c exp(-lag / tau) (0.9 at
  0.3 s, 0.4 at 3 s on data set 6); c and tau are fitted to the correlation of pairs binned by lag
  (``LAG_EDGES_S``), and sqrt(c) times the relative sigma is the part a filter can estimate as a
  Gauss-Markov state per landmark (``range_correlated_sigma_per_m``, ``range_correlation_s``).
  The bearing error persists too (a barcode read a little off centre stays off while the robot
  keeps looking): the same fit on each robot's bearing residuals in units of its own sigma gives the
  fraction c of a camera's bearing variance that persists and its correlation time
  (``bearing_correlated_fraction``, ``bearing_correlation_s``).
Pooled over the robots: one datasheet for the swarm, as a vehicle maker would print one; the camera
sigmas also per robot (``sighting_sigmas``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import nnls

from bus.angles import wrap_angle, wrap_angles
from bus.replay_config import CameraReadout
from sim.mrclam import MrclamData, RobotLog, delayed, pose_at
from sim.mrclam_camera import fit_readouts, rectified

OUTLIER_SIGMAS = 5.0
LAG_STEP_S, MAX_LAG_S = 0.01, 0.5
MAX_CAMERA_LATENCY_S = 0.3
RATE_STEP_S = 0.02  # Vicon differentiated over this
WINDOW_S = 5.0  # the shortest odometry window (blind_stretch sets the one used)
MOVING_MPS = 0.01  # windows where the robot is commanded to stand still say nothing about its wheels
# lag bins of the range error's correlation: short lags only, where pairs are many and tell most
LAG_EDGES_S = np.array([0.1, 0.5, 1.0, 2.0, 4.0])
MAX_CORRELATED_FRACTION = 0.95  # some of the range error is always left white
MIN_RANGE_M = 0.5  # closer, a relative range error says more about the truth's interpolation than the camera


@dataclass(frozen=True)
class Calibration:
    """Datasheet sigmas and what they were measured on."""

    odom_speed_sigma_mps: float
    odom_yaw_rate_sigma_radps: float
    odom_travel_sigma_m: float
    odom_turn_sigma_rad: float
    range_sigma_m: float
    bearing_sigma_rad: float
    range_correlated_sigma_per_m: float
    range_correlation_s: float
    bearing_correlated_fraction: float
    bearing_correlation_s: float
    sightings: int
    outliers: int
    odometry_windows: int
    odom_lag_s: float
    interval_s: tuple[float, float]
    camera_latency_s: float = 0.0
    readouts: tuple[CameraReadout, ...] = ()  # each robot's camera readout, in ``robots`` order


def landmark_sightings(log: RobotLog, landmarks: dict[int, np.ndarray], t0: float, t1: float) -> np.ndarray:
    """[t s, subject, true range m, range residual m, bearing residual rad] (k, 5) of the robot's
    sightings in [t0, t1) of the landmarks in ``landmarks`` (subject -> surveyed position (2,) m),
    where Vicon has the robot."""
    s = log.sightings[(log.sightings[:, 0] >= t0) & (log.sightings[:, 0] < t1)]
    s = s[np.isin(s[:, 1], list(landmarks))]
    pose = pose_at(log.groundtruth, s[:, 0]).reshape(-1, 3)
    where = np.array([landmarks[int(subject)] for subject in s[:, 1]]).reshape(-1, 2)
    d = where - pose[:, :2]
    true_range = np.hypot(d[:, 0], d[:, 1])
    out = np.column_stack(
        [s[:, :2], true_range, s[:, 2] - true_range, wrap_angles(s[:, 3] - (np.arctan2(d[:, 1], d[:, 0]) - pose[:, 2]))]
    )
    return out[np.all(np.isfinite(out), axis=1)]


def sighting_residuals(log: RobotLog, landmarks: dict[int, np.ndarray], t0: float, t1: float) -> np.ndarray:
    """[range m, bearing rad] residuals (k, 2) of :func:`landmark_sightings`."""
    return landmark_sightings(log, landmarks, t0, t1)[:, 3:5]


def range_errors(log: RobotLog, landmarks: dict[int, np.ndarray], t0: float, t1: float) -> np.ndarray:
    """[t s, subject, true range m, range error m] (k, 4) of :func:`landmark_sightings` at least
    MIN_RANGE_M away."""
    rows = landmark_sightings(log, landmarks, t0, t1)
    return rows[rows[:, 2] >= MIN_RANGE_M, :4]


def bearing_residuals(log: RobotLog, landmarks: dict[int, np.ndarray], t0: float, t1: float) -> np.ndarray:
    """[t s, subject, bearing residual rad] (k, 3) of :func:`landmark_sightings`."""
    return landmark_sightings(log, landmarks, t0, t1)[:, [0, 1, 4]]


def _inliers(residuals: np.ndarray) -> np.ndarray:
    """Mask (k,) of residuals within OUTLIER_SIGMAS robust sigmas of their median."""
    centre = np.median(residuals)
    spread = 1.4826 * np.median(np.abs(residuals - centre))
    return np.abs(residuals - centre) <= OUTLIER_SIGMAS * max(spread, 1e-9)


def _lag_products(t: np.ndarray, e: np.ndarray, sums: np.ndarray, counts: np.ndarray, lags: np.ndarray) -> None:
    """Add to the per-bin sums the products e_i e_j, counts and lags of the pairs of one landmark's
    sightings (times t (k,) s, sorted; errors e (k,)) whose lag falls in a LAG_EDGES_S bin."""
    for step in range(1, len(t)):
        lag = t[step:] - t[:-step]
        if lag.min() > LAG_EDGES_S[-1]:
            return
        bins = np.digitize(lag, LAG_EDGES_S) - 1
        inside = (bins >= 0) & (bins < len(sums))
        np.add.at(sums, bins[inside], e[step:][inside] * e[:-step][inside])
        np.add.at(counts, bins[inside], 1)
        np.add.at(lags, bins[inside], lag[inside])


def range_correlation(errors: list[np.ndarray]) -> tuple[float, float, float]:
    """(sigma, c, tau s) of the relative range error (error / true range): its RMS, and
    rho(lag) ~ c exp(-lag / tau) fitted to the correlation of pairs of sightings of one landmark by
    one robot, binned by LAG_EDGES_S; ``errors`` holds each robot's :func:`range_errors` rows."""
    return _persistence([np.column_stack([rows[:, :2], rows[:, 3] / rows[:, 2]]) for rows in errors])


def bearing_correlation(residuals: list[np.ndarray]) -> tuple[float, float]:
    """(c, tau s) of the bearing error: rho(lag) ~ c exp(-lag / tau) as for the range, on each robot's
    bearing residuals in units of its own robust sigma (cameras differ: c is the fraction of each
    one's bearing variance that persists); ``residuals`` holds each robot's rows [t s, subject,
    bearing residual rad] (:func:`bearing_residuals`)."""
    scaled = []
    for rows in residuals:
        if len(rows) >= 20:
            scaled.append(np.column_stack([rows[:, :2], rows[:, 2] / max(_robust_rms(rows[:, 2])[0], 1e-9)]))
    if not scaled:
        return 0.0, 1.0
    _, c, tau = _persistence(scaled)
    return c, tau


def _persistence(errors: list[np.ndarray]) -> tuple[float, float, float]:
    """(sigma, c, tau s) of an error series: its robust RMS, and rho(lag) ~ c exp(-lag / tau) fitted
    to the correlation of pairs of one robot's errors on one subject, binned by LAG_EDGES_S;
    ``errors`` holds each robot's rows [t s, subject, error]."""
    rows = np.vstack(errors)
    keep = _inliers(rows[:, 2])
    mean, var = float(np.mean(rows[keep, 2])), float(np.var(rows[keep, 2]))
    sums, counts, lags = (np.zeros(len(LAG_EDGES_S) - 1) for _ in range(3))
    for robot_rows in errors:
        e = robot_rows[:, 2]
        ok = _inliers(e) if len(e) else np.zeros(0, bool)
        for subject in np.unique(robot_rows[ok, 1]):
            mine = ok & (robot_rows[:, 1] == subject)
            _lag_products(robot_rows[mine, 0], e[mine] - mean, sums, counts, lags)
    rho = sums / np.maximum(counts, 1) / max(var, 1e-12)
    usable = (counts >= 20) & (rho > 3.0 / np.sqrt(np.maximum(counts, 1)))  # 3 standard errors of no correlation
    if usable.sum() < 2:
        return float(np.sqrt(var)), 0.0, 1.0
    mid = lags[usable] / counts[usable]
    slope, intercept = np.polyfit(mid, np.log(rho[usable]), 1, w=np.sqrt(counts[usable]))
    tau = float(-1.0 / slope) if slope < 0 else float(LAG_EDGES_S[-1])
    return float(np.sqrt(var)), float(min(np.exp(intercept), MAX_CORRELATED_FRACTION)), tau


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


def _robust_rms(residuals: np.ndarray) -> tuple[float, int]:
    """RMS of the residuals (k,) within OUTLIER_SIGMAS robust sigmas of their median, and how many lie beyond."""
    inside = _inliers(residuals)
    return float(np.sqrt(np.mean(residuals[inside] ** 2))), int((~inside).sum())


def calibrate(data: MrclamData, interval_s: tuple[float, float], robots: tuple[int, ...]) -> Calibration:
    """The datasheet of ``robots`` measured on ``interval_s`` of ``data`` (see the module docstring)."""
    t0, t1 = interval_s
    latency = camera_latency(data, interval_s, robots)
    readouts = camera_readouts(data, interval_s, robots, latency)
    logs = {r: rectified(delayed(data.robots[r], 0.0, latency), readout) for r, readout in zip(robots, readouts)}
    residuals = np.vstack([sighting_residuals(logs[r], _landmark_positions(data), t0, t1) for r in robots])
    lags = np.arange(0.0, MAX_LAG_S + 1e-9, LAG_STEP_S)
    lag = float(lags[np.argmin(sum(lag_mismatch(data.robots[r], t0, t1, lags) for r in robots))])
    window = blind_stretch(data, interval_s, robots)
    windows = [odometry_errors(delayed(data.robots[r], lag), t0, t1, window) for r in robots]
    odometry, extents = np.vstack([w[0] for w in windows]), np.vstack([w[1] for w in windows])
    if len(residuals) < 20 or len(odometry) < 10:
        raise ValueError(
            f"too little to calibrate on in [{t0:g}, {t1:g}] s: {len(residuals)} landmark sightings, "
            f"{len(odometry)} moving odometry windows (need 20 and 10)"
        )
    range_sigma, range_out = _robust_rms(residuals[:, 0])
    bearing_sigma, bearing_out = _robust_rms(residuals[:, 1])
    periods = [np.median(np.diff(data.robots[r].odometry[:, 0])) for r in robots]
    period = float(np.mean(periods))
    along_per_s, along_per_m, heading_per_s, heading_per_rad = growth_rates(odometry, extents)
    relative_sigma, correlated, tau = range_correlation(
        [range_errors(logs[r], _landmark_positions(data), t0, t1) for r in robots]
    )
    bearing_persisting, bearing_tau = bearing_correlation(
        [bearing_residuals(logs[r], _landmark_positions(data), t0, t1) for r in robots]
    )
    return Calibration(
        float(np.sqrt(along_per_s / period)),
        float(np.sqrt(heading_per_s / period)),
        float(np.sqrt(along_per_m)),
        float(np.sqrt(heading_per_rad)),
        range_sigma,
        bearing_sigma,
        float(np.sqrt(correlated) * relative_sigma),
        tau,
        bearing_persisting,
        bearing_tau,
        len(residuals),
        max(range_out, bearing_out),
        len(odometry),
        lag,
        (float(t0), float(t1)),
        latency,
        readouts,
    )


def camera_readouts(
    data: MrclamData, interval_s: tuple[float, float], robots: tuple[int, ...], camera_latency_s: float
) -> tuple[CameraReadout, ...]:
    """Each robot's camera readout (sim.mrclam_camera) fitted on ``interval_s``, its sightings
    restamped by ``camera_latency_s``, against the surveyed landmarks and every robot's Vicon track."""
    targets = {**_landmark_positions(data), **{r: log.groundtruth for r, log in data.robots.items()}}
    readouts = fit_readouts({r: delayed(data.robots[r], 0.0, camera_latency_s) for r in robots}, targets, *interval_s)
    return tuple(readouts[r] for r in robots)


def blind_stretch(data: MrclamData, interval_s: tuple[float, float], robots: tuple[int, ...]) -> float:
    """How long (s) the odometry has to carry a robot alone, typically: the mean length of the gaps
    between its landmark sightings on ``interval_s``, weighted by their length (the gap a moment of
    the interval lies in, on average), pooled over ``robots``; at least WINDOW_S."""
    landmarks = list(_landmark_positions(data))
    t0, t1 = interval_s
    gaps = []
    for robot in robots:
        t = data.robots[robot].sightings
        t = t[(t[:, 0] >= t0) & (t[:, 0] < t1) & np.isin(t[:, 1], landmarks), 0]
        gaps.append(np.diff(np.concatenate([[t0], np.sort(t), [t1]])))
    g = np.concatenate(gaps)
    return max(WINDOW_S, float(np.sum(g**2) / max(np.sum(g), 1e-9)))


def camera_latency(data: MrclamData, interval_s: tuple[float, float], robots: tuple[int, ...]) -> float:
    """The sightings' latency (s) that best explains the landmark bearings on ``interval_s`` (module
    docstring): the robust RMS of the bearing residuals, pooled over ``robots``, minimised on a grid."""
    landmarks = _landmark_positions(data)
    grid = np.arange(0.0, MAX_CAMERA_LATENCY_S + 1e-9, LAG_STEP_S)
    spread = []
    for latency in grid:
        bearings = [
            sighting_residuals(delayed(data.robots[r], 0.0, latency), landmarks, *interval_s)[:, 1] for r in robots
        ]
        pooled = np.concatenate(bearings)
        spread.append(_robust_rms(pooled)[0] if len(pooled) else np.inf)
    return float(grid[int(np.argmin(spread))])


def sighting_sigmas(
    data: MrclamData,
    interval_s: tuple[float, float],
    robots: tuple[int, ...],
    camera_latency_s: float = 0.0,
    readouts: tuple[CameraReadout, ...] = (),
) -> tuple[tuple[float, float], ...]:
    """Each robot's own camera: (range sigma per metre of range, bearing sigma rad) of its landmark
    sightings on ``interval_s``, restamped by ``camera_latency_s`` and read back through its readout
    in ``readouts`` (robust RMS of error / true range, and of the bearing error; the pooled sigmas
    where a robot saw fewer than 20 landmarks)."""
    landmarks = _landmark_positions(data)
    logs = {
        robot: rectified(delayed(data.robots[robot], 0.0, camera_latency_s), readout)
        for robot, readout in zip(robots, readouts or (CameraReadout(),) * len(robots))
    }
    errors = {robot: range_errors(logs[robot], landmarks, *interval_s) for robot in robots}
    bearings = {robot: sighting_residuals(logs[robot], landmarks, *interval_s)[:, 1] for robot in robots}
    pooled = (
        _robust_rms(np.concatenate([e[:, 3] / e[:, 2] for e in errors.values()]))[0],
        _robust_rms(np.concatenate(list(bearings.values())))[0],
    )
    out = []
    for robot in robots:
        if len(errors[robot]) < 20 or len(bearings[robot]) < 20:
            out.append(pooled)
        else:
            out.append((_robust_rms(errors[robot][:, 3] / errors[robot][:, 2])[0], _robust_rms(bearings[robot])[0]))
    return tuple(out)


def _landmark_positions(data: MrclamData) -> dict[int, np.ndarray]:
    return {int(row[0]): row[1:3].copy() for row in data.landmarks}
