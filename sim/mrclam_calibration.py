"""Noise datasheet of an MRCLAM data set, calibrated against its ground truth on an interval that is
then never scored (Leung et al., IJRR 2011). Pure: data in, numbers out.

- Sightings (camera range and bearing to landmarks): residuals against the range and bearing the
  Vicon pose and the surveyed landmark give; gross misreadings (beyond ``sim.robust.OUTLIER_SIGMAS`` robust
  sigmas: wrong barcode, occlusion) are counted, not folded into the sigma; the sigma is the RMS of
  the rest, bias included (the filter has no bias state).
- Odometry: its lag and its noise (sim.mrclam_odometry).
- Camera latency: a sighting is stamped when the image was read, some tens of milliseconds after it
  was taken; while the robot turns, that shows as a bearing error of yaw rate times latency, the
  same for every sighting of the turn. The latency (one for the swarm, on the ``LAG_STEP_S`` grid up
  to ``MAX_CAMERA_LATENCY_S``) is the one that minimises the robust RMS of the landmark bearings'
  residuals; every sighting statistic below is taken on the sightings restamped with it, and so is
  the replay (``replay.camera_latency_s``).
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

from bus.angles import wrap_angles
from bus.replay_config import CameraReadout
from sim.mrclam import MrclamData, RobotLog, delayed, pose_at
from sim.mrclam_camera import MIN_RANGE_M, fit_readouts, rectified
from sim.mrclam_odometry import LAG_STEP_S, fit_odometry
from sim.robust import inliers, robust_rms

MAX_CAMERA_LATENCY_S = 0.3
# lag bins of the range error's correlation: short lags only, where pairs are many and tell most
LAG_EDGES_S = np.array([0.1, 0.5, 1.0, 2.0, 4.0])
MAX_CORRELATED_FRACTION = 0.95  # some of the range error is always left white


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
            scaled.append(np.column_stack([rows[:, :2], rows[:, 2] / max(robust_rms(rows[:, 2])[0], 1e-9)]))
    if not scaled:
        return 0.0, 1.0
    _, c, tau = _persistence(scaled)
    return c, tau


def _persistence(errors: list[np.ndarray]) -> tuple[float, float, float]:
    """(sigma, c, tau s) of an error series: its robust RMS, and rho(lag) ~ c exp(-lag / tau) fitted
    to the correlation of pairs of one robot's errors on one subject, binned by LAG_EDGES_S;
    ``errors`` holds each robot's rows [t s, subject, error]."""
    rows = np.vstack(errors)
    keep = inliers(rows[:, 2])
    mean, var = float(np.mean(rows[keep, 2])), float(np.var(rows[keep, 2]))
    sums, counts, lags = (np.zeros(len(LAG_EDGES_S) - 1) for _ in range(3))
    for robot_rows in errors:
        e = robot_rows[:, 2]
        ok = inliers(e) if len(e) else np.zeros(0, bool)
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


def calibrate(data: MrclamData, interval_s: tuple[float, float], robots: tuple[int, ...]) -> Calibration:
    """The datasheet of ``robots`` measured on ``interval_s`` of ``data`` (see the module docstring)."""
    t0, t1 = interval_s
    latency = camera_latency(data, interval_s, robots)
    readouts = camera_readouts(data, interval_s, robots, latency)
    logs = {r: rectified(delayed(data.robots[r], 0.0, latency), readout) for r, readout in zip(robots, readouts)}
    residuals = np.vstack([sighting_residuals(logs[r], _landmark_positions(data), t0, t1) for r in robots])
    odometry = fit_odometry(data, interval_s, robots, list(_landmark_positions(data)))
    if len(residuals) < 20 or odometry.windows < 10:
        raise ValueError(
            f"too little to calibrate on in [{t0:g}, {t1:g}] s: {len(residuals)} landmark sightings, "
            f"{odometry.windows} moving odometry windows (need 20 and 10)"
        )
    range_sigma, range_out = robust_rms(residuals[:, 0])
    bearing_sigma, bearing_out = robust_rms(residuals[:, 1])
    relative_sigma, correlated, tau = range_correlation(
        [range_errors(logs[r], _landmark_positions(data), t0, t1) for r in robots]
    )
    bearing_persisting, bearing_tau = bearing_correlation(
        [bearing_residuals(logs[r], _landmark_positions(data), t0, t1) for r in robots]
    )
    return Calibration(
        odometry.speed_sigma_mps,
        odometry.yaw_rate_sigma_radps,
        odometry.travel_sigma_m,
        odometry.turn_sigma_rad,
        range_sigma,
        bearing_sigma,
        float(np.sqrt(correlated) * relative_sigma),
        tau,
        bearing_persisting,
        bearing_tau,
        len(residuals),
        max(range_out, bearing_out),
        odometry.windows,
        odometry.lag_s,
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
        spread.append(robust_rms(pooled)[0] if len(pooled) else np.inf)
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
        robust_rms(np.concatenate([e[:, 3] / e[:, 2] for e in errors.values()]))[0],
        robust_rms(np.concatenate(list(bearings.values())))[0],
    )
    out = []
    for robot in robots:
        if len(errors[robot]) < 20 or len(bearings[robot]) < 20:
            out.append(pooled)
        else:
            out.append((robust_rms(errors[robot][:, 3] / errors[robot][:, 2])[0], robust_rms(bearings[robot])[0]))
    return tuple(out)


def _landmark_positions(data: MrclamData) -> dict[int, np.ndarray]:
    return {int(row[0]): row[1:3].copy() for row in data.landmarks}
