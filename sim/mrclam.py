"""Reading a UTIAS MRCLAM data set (Leung, Halpern, Barfoot and Liu, "The UTIAS Multi-Robot
Cooperative Localization and Mapping Dataset", IJRR 30(8), 2011): five robots' odometry, camera
sightings of landmarks and of each other, Vicon ground truth, surveyed landmarks. Pure: files in,
arrays out; the replay world builds on it.

Layout (any of data sets 1-9): ``Barcodes.dat`` (subject, barcode), ``Landmark_Groundtruth.dat``
(subject, x, y, sigma_x, sigma_y), and per robot r ``Robot<r>_Groundtruth.dat`` (t, x, y, theta),
``Robot<r>_Odometry.dat`` (t, v, w) and ``Robot<r>_Measurement.dat`` (t, barcode, range, bearing);
whitespace-separated numbers, ``#`` comment lines. Subjects 1-5 are the robots, the rest landmarks.
Sightings of barcodes not in ``Barcodes.dat`` happen; they are skipped and counted per robot.

Every problem is a ``DataError`` naming the file and, for a bad line, its number and contents.
"""

from __future__ import annotations

import dataclasses
import math
import tarfile
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bus.angles import wrap_angles
from bus.errors import SwarmlocError

ROBOTS = (1, 2, 3, 4, 5)
MAX_LINE_SHOWN = 60


class DataError(SwarmlocError):
    """A data set file is missing or malformed."""


@dataclass(frozen=True)
class RobotLog:
    """One robot's recordings, times in seconds since the data set's start: ground truth (k, 4)
    [t, x m, y m, theta rad], odometry (k, 3) [t, v m/s, w rad/s], sightings (k, 4) [t, subject,
    range m, bearing rad] with barcodes mapped to subjects."""

    robot: int
    groundtruth: np.ndarray
    odometry: np.ndarray
    sightings: np.ndarray
    unknown_barcodes: int


@dataclass(frozen=True)
class MrclamData:
    """A whole data set: the robots' logs, the surveyed landmarks (m, 5) [subject, x, y, sigma_x,
    sigma_y] and the absolute time (s, Unix) the relative times count from."""

    robots: dict[int, RobotLog]
    landmarks: np.ndarray
    start_s: float

    @property
    def duration_s(self) -> float:
        """Until the last ground truth of any robot."""
        return max(float(log.groundtruth[-1, 0]) for log in self.robots.values() if len(log.groundtruth))


def read_table(path: Path, width: int) -> np.ndarray:
    """The numbers of a data file as (k, width) floats; a missing file, a line of another width or a
    non-number is a DataError with the file name, the line number and the line. Blank lines and
    lines starting with ``#`` are skipped."""
    if not path.is_file():
        raise DataError(f"{path.name} is missing from {path.parent}")
    with path.open("r", encoding="utf-8", errors="replace") as handle:
        lines = handle.read().split("\n")  # the lines iterating the file gives (newlines translated)
    data = [line for line in lines if line.strip() and not line.lstrip().startswith("#")]
    try:  # numpy's parser (C): a data set's 600,000 lines in a tenth of the time of the loop below
        table = np.loadtxt(data, dtype=float, comments=None, ndmin=2) if data else None
    except ValueError:
        table = None
    if table is None or table.shape[1] != width or not np.isfinite(table).all():
        return _read_line_by_line(path, lines, width)  # the same rule, and the error names the line
    return table


def _read_line_by_line(path: Path, lines: list[str], width: int) -> np.ndarray:
    """``read_table`` one line at a time with Python's float: what numpy's parser does not take."""
    rows = []
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        try:
            values = [float(f) for f in text.split()]
        except ValueError:
            values = []
        if len(values) != width or not all(math.isfinite(v) for v in values):
            shown = text if len(text) <= MAX_LINE_SHOWN else text[:MAX_LINE_SHOWN] + "..."
            raise DataError(f"{path.name} line {number}: expected {width} numbers, got {shown!r}")
        rows.append(values)
    return np.array(rows, dtype=float).reshape(-1, width)


def _increasing_times(table: np.ndarray, path: Path) -> None:
    bad = np.flatnonzero(np.diff(table[:, 0]) < 0)
    if len(bad):
        raise DataError(f"{path.name}: time goes backwards at data row {int(bad[0]) + 2}")


def load_mrclam(path: Path) -> MrclamData:
    """A data set from its directory, or from its ``.tar.xz`` (unpacked to a temporary directory)."""
    path = Path(path)
    if path.is_file() and path.name.endswith((".tar.xz", ".tar.gz", ".tar", ".tgz")):
        with tempfile.TemporaryDirectory(prefix="mrclam-") as tmp:
            try:
                with tarfile.open(path) as archive:
                    _extract_safely(archive, Path(tmp))
            except (tarfile.TarError, OSError, EOFError) as exc:
                raise DataError(f"{path.name} is not a readable archive ({exc})") from None
            folders = sorted({p.parent for p in Path(tmp).rglob("Barcodes.dat")})
            if len(folders) != 1:
                raise DataError(f"{path.name} holds {len(folders)} data sets (Barcodes.dat files); expected one")
            return _load_directory(folders[0])
    if not path.is_dir():
        raise DataError(f"{path} is neither a data set directory nor a .tar.xz archive")
    return _load_directory(path)


def _extract_safely(archive: tarfile.TarFile, into: Path) -> None:
    """Regular files and folders only, nothing outside ``into`` (the "data" filter where Python has it)."""
    if hasattr(tarfile, "data_filter"):
        archive.extractall(into, filter="data")
        return
    for member in archive.getmembers():
        target = (into / member.name).resolve()
        if not (member.isfile() or member.isdir()) or into.resolve() not in target.parents and target != into.resolve():
            raise DataError(f"{member.name}: not a plain file inside the archive's folder")
    archive.extractall(into)


def _load_directory(folder: Path) -> MrclamData:
    barcodes = read_table(folder / "Barcodes.dat", 2)
    subject_of = {int(b): int(s) for s, b in barcodes}
    landmarks = read_table(folder / "Landmark_Groundtruth.dat", 5)
    tables = {}
    for robot in ROBOTS:
        for kind, width in (("Groundtruth", 4), ("Odometry", 3), ("Measurement", 4)):
            file = folder / f"Robot{robot}_{kind}.dat"
            tables[robot, kind] = read_table(file, width)
            if kind != "Measurement":
                _increasing_times(tables[robot, kind], file)
    starts = [tables[r, k][0, 0] for r in ROBOTS for k in ("Groundtruth", "Odometry") if len(tables[r, k])]
    if not starts:
        raise DataError(f"{folder}: no ground truth and no odometry in any robot's files")
    start_s = float(min(starts))
    robots = {}
    for robot in ROBOTS:
        raw = tables[robot, "Measurement"]
        subjects = np.array([subject_of.get(int(b), 0) for b in raw[:, 1]], dtype=float)
        known = subjects > 0
        sightings = np.column_stack([raw[known, 0] - start_s, subjects[known], raw[known, 2], raw[known, 3]])
        sightings = sightings[np.argsort(sightings[:, 0], kind="stable")]
        groundtruth, odometry = tables[robot, "Groundtruth"].copy(), tables[robot, "Odometry"].copy()
        groundtruth[:, 0] -= start_s
        odometry[:, 0] -= start_s
        robots[robot] = RobotLog(robot, groundtruth, odometry, sightings.reshape(-1, 4), int((~known).sum()))
    return MrclamData(robots, landmarks, start_s)


def delayed(log: RobotLog, lag_s: float, camera_latency_s: float = 0.0) -> RobotLog:
    """The robot's log with its odometry stamped ``lag_s`` later (when each command takes effect) and
    its sightings ``camera_latency_s`` earlier (when the image was taken, not when it was read)."""
    odometry, sightings = log.odometry.copy(), log.sightings.copy()
    odometry[:, 0] += lag_s
    sightings[:, 0] -= camera_latency_s
    return dataclasses.replace(log, odometry=odometry, sightings=sightings)


def pose_at(groundtruth: np.ndarray, t_s: np.ndarray, max_gap_s: float = 0.5) -> np.ndarray:
    """Ground truth (k, 4) [t, x, y, theta] interpolated at times ``t_s`` (n,): poses (n, 3), the
    heading unwrapped before interpolating and wrapped after; NaN rows outside the recording or
    between two samples more than ``max_gap_s`` apart (Vicon lost the robot)."""
    t_s = np.asarray(t_s, dtype=float)
    out = np.full((len(t_s), 3), np.nan)
    times = groundtruth[:, 0]
    if len(times) < 2:
        return out
    after = np.clip(np.searchsorted(times, t_s), 1, len(times) - 1)
    on_sample = (times[after] == t_s) | (times[after - 1] == t_s)
    ok = (t_s >= times[0]) & (t_s <= times[-1]) & (on_sample | (times[after] - times[after - 1] <= max_gap_s))
    heading = np.unwrap(groundtruth[:, 3])
    for column, values in enumerate((groundtruth[:, 1], groundtruth[:, 2], heading)):
        out[ok, column] = np.interp(t_s[ok], times, values)
    out[ok, 2] = wrap_angles(out[ok, 2])
    return out
