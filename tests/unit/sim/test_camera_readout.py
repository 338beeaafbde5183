"""A camera's readout (sim.mrclam_camera): fitted on sightings a known readout misread, it recovers
that readout, reads the sightings back to the truth, ignores misread barcodes, and stays identity
where there is too little to fit; on the data set excerpt it takes the relative range error's spread
from several per cent to about one."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from bus.replay_config import CameraReadout
from sim.mrclam import RobotLog, delayed, load_mrclam
from sim.mrclam_calibration import camera_readouts, range_errors
from sim.mrclam_camera import MIN_SIGHTINGS, fit_readouts, read_back, rectified

EXCERPT = Path(__file__).resolve().parents[2] / "data" / "MRCLAM_Dataset6_first240s.tar.xz"
TRUE = CameraReadout(
    span_rad=0.6,
    landmark_scale=0.03,
    landmark_offset_m=0.04,
    robot_scale=0.05,
    robot_offset_m=-0.02,
    tilt=-0.03,
    curvature=-0.47,
    bearing_offset_rad=-0.02,
    bearing_scale=0.02,
    bearing_curvature=-0.03,
)
PARKED = {2: np.array([1.5, 1.5]), 3: np.array([3.0, -3.0])}
SECOND = TRUE.model_copy(  # another copy of the lens; a robot's barcode is read as much longer as by the first
    update={"curvature": -0.52, "tilt": 0.01, "landmark_scale": 0.05, "robot_scale": 0.07, "bearing_offset_rad": 0.01}
)
LANDMARKS = {6: np.array([1.0, 0.0]), 7: np.array([0.0, 2.5]), 8: np.array([-4.0, 0.0]), 9: np.array([0.0, -5.5])}


def misread(rows: np.ndarray, readout: CameraReadout) -> tuple[np.ndarray, np.ndarray]:
    """Range and bearing (k,) as ``readout``'s camera reads targets at rows [range m, bearing rad, robot]."""
    r, b, robot = rows[:, 0], rows[:, 1], rows[:, 2] > 0
    scale = np.where(robot, readout.robot_scale, readout.landmark_scale)
    offset = np.where(robot, readout.robot_offset_m, readout.landmark_offset_m)
    read_range = r * (1 + scale + readout.tilt * b + readout.curvature * b**2) + offset
    read_bearing = b + readout.bearing_offset_rad + readout.bearing_scale * b + readout.bearing_curvature * b**2
    return read_range, read_bearing


def spinning_robot(rng: np.random.Generator, count: int, readout: CameraReadout, gross: float = 0.0):
    """A robot at the origin turning in place, seeing the four landmarks and the two robots parked
    (PARKED) through a camera with ``readout``, white noise of 0.5 % and 5 mrad; a share ``gross``
    of the sightings misread wildly. Returns its log and the targets."""
    t = np.sort(rng.uniform(0.0, 100.0, count))
    heading = 0.07 * t
    subjects = rng.choice([6, 7, 8, 9, 2, 3], count)
    where = np.array([{**LANDMARKS, **PARKED}[s] for s in subjects])
    true_range = np.hypot(where[:, 0], where[:, 1])
    bearing = np.angle(np.exp(1j * (np.arctan2(where[:, 1], where[:, 0]) - heading)))
    ahead = np.abs(bearing) < 0.6  # the camera's field of view
    t, subjects, true_range, bearing = t[ahead], subjects[ahead], true_range[ahead], bearing[ahead]
    read_range, read_bearing = misread(np.column_stack([true_range, bearing, np.isin(subjects, [2, 3])]), readout)
    read_range *= 1 + rng.normal(0, 0.005, len(t))
    read_bearing += rng.normal(0, 0.005, len(t))
    wild = rng.random(len(t)) < gross
    read_range[wild] *= rng.uniform(0.3, 2.0, wild.sum())
    read_bearing[wild] += rng.uniform(-0.5, 0.5, wild.sum())
    grid = np.arange(0.0, 100.01, 0.01)
    truth = np.column_stack([grid, np.zeros_like(grid), np.zeros_like(grid), np.angle(np.exp(1j * 0.07 * grid))])
    log = RobotLog(1, truth, np.zeros((0, 3)), np.column_stack([t, subjects, read_range, read_bearing]), 0)
    parked = {
        robot: np.column_stack([grid, np.full_like(grid, x), np.full_like(grid, y), np.zeros_like(grid)])
        for robot, (x, y) in PARKED.items()
    }
    return log, {**LANDMARKS, **parked}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_fit_recovers_the_readout_that_misread_the_sightings(seed):
    rng = np.random.default_rng(seed)
    (log, targets), (other, _) = spinning_robot(rng, 6000, TRUE, gross=0.03), spinning_robot(rng, 6000, SECOND)
    fitted = fit_readouts({1: log, 2: other}, targets, 0.0, 100.0)[1]
    assert fitted.span_rad == pytest.approx(0.6, abs=0.02)
    for name, value in TRUE.model_dump(exclude={"span_rad"}).items():
        tolerance = 0.05 if name == "curvature" else 0.01
        assert getattr(fitted, name) == pytest.approx(value, abs=tolerance), name


def test_reading_back_undoes_the_misreading():
    rng = np.random.default_rng(3)
    rows = np.column_stack([rng.uniform(0.6, 5.0, 500), rng.uniform(-0.59, 0.59, 500), rng.random(500) < 0.3])
    read_range, read_bearing = misread(rows, TRUE)
    subjects = np.where(rows[:, 2] > 0, 2, 7)
    back = read_back(np.column_stack([np.zeros(500), subjects, read_range, read_bearing]), TRUE)
    assert np.max(np.abs(back[:, 3] - rows[:, 1])) < 1e-4
    assert np.max(np.abs(back[:, 2] / rows[:, 0] - 1)) < 1e-4


def test_without_two_cameras_to_learn_the_lens_from_every_camera_reads_as_recorded():
    rng = np.random.default_rng(4)
    (log, targets), (few, _) = spinning_robot(rng, 6000, TRUE), spinning_robot(rng, 60, TRUE)
    assert len(few.sightings) < MIN_SIGHTINGS
    fitted = fit_readouts({1: log, 2: few}, targets, 0.0, 100.0)
    assert fitted == {1: CameraReadout(), 2: CameraReadout()}
    assert rectified(log, fitted[1]) is log


def test_a_camera_with_too_few_sightings_reads_through_the_others_mean():
    rng = np.random.default_rng(6)
    (log, targets), (other, _), (few, _) = (
        spinning_robot(rng, n, c) for n, c in ((6000, TRUE), (6000, SECOND), (40, TRUE))
    )
    fitted = fit_readouts({1: log, 2: other, 3: few}, targets, 0.0, 100.0)
    assert fitted[3].curvature == pytest.approx((TRUE.curvature + SECOND.curvature) / 2, abs=0.03)


def test_on_the_excerpt_the_relative_range_error_falls_to_about_a_per_cent():
    data = load_mrclam(EXCERPT)
    robots = (1, 2, 3, 4, 5)
    readouts = camera_readouts(data, (0.0, 120.0), robots, 0.04)
    landmarks = {int(row[0]): row[1:3] for row in data.landmarks}

    def spread(window, readers):
        logs = [rectified(delayed(data.robots[r], 0.0, 0.04), c) for r, c in zip(robots, readers)]
        errors = np.vstack([range_errors(log, landmarks, *window) for log in logs])
        relative = errors[:, 3] / errors[:, 2]
        return 1.4826 * np.median(np.abs(relative - np.median(relative)))

    as_read = spread((120.0, 240.0), [CameraReadout()] * 5)
    read_back_ = spread((120.0, 240.0), readouts)  # out of sample: fitted on 0-120 s
    assert as_read > 0.03 and read_back_ < 0.5 * as_read


def test_a_camera_that_saw_one_side_takes_the_others_curves_and_reads_nothing_absurd():
    rng = np.random.default_rng(5)
    (whole, targets), (other, _), (third, _) = (spinning_robot(rng, 6000, c) for c in (TRUE, SECOND, TRUE))
    half = dataclasses.replace(third, sightings=third.sightings[third.sightings[:, 3] < -0.1])  # its left only
    fitted = fit_readouts({1: whole, 2: other, 3: half}, targets, 0.0, 100.0)
    assert fitted[3].curvature == pytest.approx(TRUE.curvature, abs=0.1)  # between the two references'
    assert fitted[3].landmark_scale == pytest.approx(TRUE.landmark_scale, abs=0.01)  # its own
    assert fitted[3].bearing_offset_rad == pytest.approx(TRUE.bearing_offset_rad, abs=0.005)
    # far outside what was fitted, a bearing reads back through the curves' edge, not their extrapolation
    wide = np.array([[0.0, 7.0, 3.0, 1.4], [0.0, 7.0, 3.0, -1.4]])
    back = read_back(wide, fitted[3])
    assert np.all(np.isfinite(back)) and np.all((back[:, 2] > 2.0) & (back[:, 2] < 4.0))


def test_on_the_excerpt_every_sighting_reads_back_to_a_sane_range():
    """Robot 1 sees landmarks on its right only in the excerpt's first two minutes: fitted alone, its
    curves bent its far-left sightings to negative ranges, which no vehicle can use."""
    data = load_mrclam(EXCERPT)
    readouts = camera_readouts(data, (0.0, 120.0), (1, 2, 3, 4, 5), 0.04)
    for robot, readout in zip((1, 2, 3, 4, 5), readouts):
        ranges = read_back(data.robots[robot].sightings, readout)[:, 2]
        assert np.all(ranges > 0.1) and np.all(ranges < 10.0), robot
