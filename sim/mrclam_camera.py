"""A robot camera's systematic misreading of range and bearing (bus.replay_config.CameraReadout),
fitted against ground truth and read back out of every sighting, as a camera driver applies its
calibration. Pure: data in, numbers out.

An MRCLAM camera reads a barcode's range from its size in the image and its bearing from where in
the image it is. Against Vicon, on data set 6, the range error is not a white 4 %: it follows the
target's place in the image (read some 3 % long at the centre, 8-10 % short at the edges, +-0.5 rad
off the axis: the lens), it leans with the bearing on some cameras (robot 5 reads 2-3 % short on
its left and as much long on its right), and each camera reads landmarks, and robots (their
barcodes differ), long by a few per cent of its own; the bearings have an offset and a scale per
camera (robot 4 reads 0.02 rad to the right). Fitted on the first half of data set 6, the same
curves hold on the second: the relative range error's spread falls from 4.3 % to about 1 % on
both halves.

The fit, per robot, on its sightings at least ``MIN_RANGE_M`` away where Vicon has both ends:
robust least squares (sim.robust: rows beyond five robust sigmas of the fit dropped, three
times) of the landmarks' relative range error on [1, 1/r, b, b^2] and of their bearing error on
[1, b, b^2] (r, b: the true range and bearing); then the robots' relative range error, less the
landmarks' readout, on [1, 1/r], pooled over the cameras (a robot's barcode is another size than a
landmark's for every camera alike). A camera fitted alone on a few sightings, or on one side of its image
(robot 1 in data set 6's first two minutes), bends its curves wildly where it has no sightings, so
each camera is fitted with a prior (empirical Bayes): the mean and the camera-to-camera spread of
the readouts of the cameras with ``MIN_OWN`` sightings on both sides of their image, no narrower than
``PRIOR_FLOOR``. Its own sightings decide what they can tell (robot 4's bearing scale, seen on its
right only), the others the rest. No curve is taken beyond the bearings they were fitted on
(``span_rad``), and a range is read back to between half and twice what was read.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from bus.angles import wrap_angles
from bus.replay_config import CameraReadout
from sim.mrclam import RobotLog, pose_at
from sim.robust import robust_fit

MIN_SIGHTINGS = 50  # landmark sightings a camera needs to be fitted at all
MIN_OWN = 300  # and to be one the others' prior is taken from
PRIOR_FLOOR = (0.002, 0.005, 0.02, 0.005, 0.005, 0.05, 0.005)  # the prior's least spread (coefficients' units)
MIN_RANGE_M = 0.5
READ_BACK_ROUNDS = 3  # fixed-point steps inverting the bearing's curve
ROBOT_SUBJECTS = (1, 2, 3, 4, 5)
SIDE_RAD, COVERAGE = 0.2, 0.1  # a camera "covers" its image with a tenth of its sightings beyond 0.2 rad each side
SPAN_SHARE = 0.99  # the curves hold within the bearings 99 % of the fitted sightings were seen at
MIN_FACTOR = 0.5  # a range is read back to no less than half and no more than twice what the camera read


def sighting_geometry(
    log: RobotLog, targets: dict[int, np.ndarray], t0: float, t1: float
) -> tuple[np.ndarray, np.ndarray]:
    """The robot's sightings in [t0, t1) of the subjects in ``targets`` (subject -> true positions:
    (2,) m for a landmark, or a ground truth (k, 4) [t, x, y, theta] for a robot) at least
    MIN_RANGE_M away, where Vicon has both ends: rows [true range m, true bearing rad, range read m,
    bearing read rad] (k, 4), and whether each is of a landmark (k,) bool."""
    s = log.sightings[(log.sightings[:, 0] >= t0) & (log.sightings[:, 0] < t1)]
    s = s[np.isin(s[:, 1], list(targets))]
    pose = pose_at(log.groundtruth, s[:, 0]).reshape(-1, 3)
    where = np.full((len(s), 2), np.nan)
    for subject in np.unique(s[:, 1]).astype(int):
        mine = s[:, 1] == subject
        target = targets[subject]
        where[mine] = target if target.ndim == 1 else pose_at(target, s[mine, 0])[:, :2]
    d = where - pose[:, :2]
    rows = np.column_stack(
        [np.hypot(d[:, 0], d[:, 1]), wrap_angles(np.arctan2(d[:, 1], d[:, 0]) - pose[:, 2]), s[:, 2], s[:, 3]]
    )
    keep = np.all(np.isfinite(rows), axis=1) & (rows[:, 0] >= MIN_RANGE_M)
    return rows[keep], ~np.isin(s[keep, 1], ROBOT_SUBJECTS)


def fit_readouts(
    logs: dict[int, RobotLog], targets: dict[int, np.ndarray], t0: float, t1: float
) -> dict[int, CameraReadout]:
    """Each robot's camera readout fitted on [t0, t1) of its log (module docstring); ``targets`` as
    in :func:`sighting_geometry`. Every camera with MIN_SIGHTINGS landmark sightings is fitted with
    a prior: the mean and spread, camera to camera, of the readouts of those that saw MIN_OWN filling
    both sides of their image (:func:`covers`; empirical Bayes: one lens model, each copy a little
    different), so that what its own sightings cannot tell (the curves, from one side of the image)
    comes from the others; a camera with fewer sightings reads through that mean. With fewer than two
    such cameras there is no prior to be had, and every camera reads as recorded."""
    geometry = {robot: sighting_geometry(log, targets, t0, t1) for robot, log in logs.items()}
    seen = {robot: rows[landmark] for robot, (rows, landmark) in geometry.items()}
    references = [robot for robot, rows in seen.items() if len(rows) >= MIN_OWN and covers(rows)]
    if len(references) < 2:
        return dict.fromkeys(logs, CameraReadout())
    own = np.array([_coefficients(seen[robot]) for robot in references])
    prior = own.mean(axis=0), own.var(axis=0, ddof=1) + np.square(PRIOR_FLOOR)
    span = _span(np.vstack([seen[robot] for robot in references]))
    mean = _readout(own.mean(axis=0), span)
    out = {
        robot: mean if len(seen[robot]) < MIN_SIGHTINGS else _readout(_coefficients(seen[robot], prior), span)
        for robot in geometry
    }
    scale, offset = robot_targets(out, {robot: rows[~landmark] for robot, (rows, landmark) in geometry.items()})
    return {
        robot: readout.model_copy(
            update={
                "robot_scale": _inside(readout.landmark_scale + scale, "robot_scale"),
                "robot_offset_m": _inside(readout.landmark_offset_m + offset, "robot_offset_m"),
            }
        )
        for robot, readout in out.items()
    }


def covers(rows: np.ndarray) -> bool:
    """Whether sightings rows (k, 4) fill both sides of the image: COVERAGE of them beyond
    +-SIDE_RAD each."""
    return bool(np.mean(rows[:, 1] < -SIDE_RAD) >= COVERAGE and np.mean(rows[:, 1] > SIDE_RAD) >= COVERAGE)


def _coefficients(rows: np.ndarray, prior: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """A camera's readout coefficients (7,) [bearing offset, scale, curvature, range scale, tilt,
    curvature, offset] from its landmark sightings rows (k, 4), with an optional prior on them."""
    bearing_prior = None if prior is None else (prior[0][:3], prior[1][:3])
    range_prior = None if prior is None else (prior[0][3:], prior[1][3:])
    bearing, pointed = robust_fit(_powers(rows[:, 1], 3), wrap_angles(rows[:, 3] - rows[:, 1]), bearing_prior)
    rows = rows[pointed]  # a bearing far off (a wrong barcode, Vicon's heading lost) says nothing of the range
    r, b = rows[:, 0], rows[:, 1]
    lean, _ = robust_fit(np.column_stack([_powers(b, 3), 1 / r]), (rows[:, 2] - r) / r, range_prior)
    return np.concatenate([bearing, lean])


def _readout(coefficients: np.ndarray, span_rad: float) -> CameraReadout:
    """The readout of :func:`_coefficients`, landmark and robot terms alike, each clipped to its
    field's bounds (a wild fit stays a valid readout)."""
    b0, b1, b2, scale, tilt, curvature, offset = coefficients
    values = {
        "landmark_scale": scale,
        "landmark_offset_m": offset,
        "robot_scale": scale,
        "robot_offset_m": offset,
        "tilt": tilt,
        "curvature": curvature,
        "bearing_offset_rad": b0,
        "bearing_scale": b1,
        "bearing_curvature": b2,
        "span_rad": span_rad,
    }
    return CameraReadout(**{name: _inside(float(v), name) for name, v in values.items()})


def robot_targets(readouts: dict[int, CameraReadout], robot_rows: dict[int, np.ndarray]) -> tuple[float, float]:
    """How much longer (scale, offset m) every camera reads a robot's barcode than a landmark's (they
    differ in size, not the cameras): fitted on all cameras' robot sightings rows (k, 4) at once, each
    read back through its camera's landmark readout; (0, 0) with fewer than MIN_SIGHTINGS."""
    relative, inverse = [], []
    for robot, rows in robot_rows.items():
        readout = readouts[robot]
        r, b = rows[:, 0], rows[:, 1]
        lean = readout.landmark_scale + readout.tilt * b + readout.curvature * b**2 + readout.landmark_offset_m / r
        relative.append((rows[:, 2] - r) / r - lean)
        inverse.append(1 / r)
    y, inv = np.concatenate(relative), np.concatenate(inverse)
    if len(y) < MIN_SIGHTINGS:
        return 0.0, 0.0
    (scale, offset), _ = robust_fit(np.column_stack([np.ones(len(y)), inv]), y)
    return float(scale), float(offset)


def _span(rows: np.ndarray) -> float:
    """The bearing (rad) within which SPAN_SHARE of the sightings rows (k, 4) were seen."""
    return float(np.quantile(np.abs(rows[:, 1]), SPAN_SHARE))


def _powers(b: np.ndarray, count: int) -> np.ndarray:
    """Columns [1, b, b^2, ...] (k, count)."""
    return b[:, None] ** np.arange(count)


def _inside(value: float, name: str) -> float:
    """``value`` clipped to the bounds of CameraReadout's field ``name``."""
    field = CameraReadout.model_fields[name]
    low = next((m.ge for m in field.metadata if hasattr(m, "ge")), -np.inf)
    high = next((m.le for m in field.metadata if hasattr(m, "le")), np.inf)
    return float(np.clip(value, low, high))


def read_back(sightings: np.ndarray, readout: CameraReadout) -> np.ndarray:
    """Sightings (k, 4) [t s, subject, range m, bearing rad] as a camera without ``readout``'s
    misreading would have read them: the bearing first, the range at that bearing."""
    out = sightings.copy()
    read = sightings[:, 3]
    bearing, offset = read, readout.bearing_offset_rad
    for _ in range(READ_BACK_ROUNDS):  # b = (read - offset - curvature b^2) / (1 + scale): a contraction at |b| < 1
        bent = np.clip(bearing, -readout.span_rad, readout.span_rad)  # the curves are not extrapolated
        bearing = (read - offset - readout.bearing_curvature * bent**2) / (1 + readout.bearing_scale)
    bent = np.clip(bearing, -readout.span_rad, readout.span_rad)
    robot = np.isin(sightings[:, 1], ROBOT_SUBJECTS)
    scale = np.where(robot, readout.robot_scale, readout.landmark_scale)
    offset = np.where(robot, readout.robot_offset_m, readout.landmark_offset_m)
    factor = 1 + scale + readout.tilt * bent + readout.curvature * bent**2
    read_range = sightings[:, 2]
    out[:, 2] = np.clip(
        (read_range - offset) / np.maximum(factor, MIN_FACTOR), MIN_FACTOR * read_range, read_range / MIN_FACTOR
    )
    out[:, 3] = bearing
    return out


def rectified(log: RobotLog, readout: CameraReadout) -> RobotLog:
    """``log`` with its sightings read back through ``readout`` (:func:`read_back`)."""
    if readout == CameraReadout():
        return log
    return dataclasses.replace(log, sightings=read_back(log.sightings, readout))
