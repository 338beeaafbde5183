"""Reading MRCLAM data sets (Leung et al., IJRR 2011): a tiny excerpt round-trips (directory and
.tar.xz), barcodes become subjects and unknown ones are skipped and counted, every malformed case is
one clear error naming the file (and the line); data set 6 itself when it is on this machine; any
table reads as Python's float reads each of its lines."""

import re
import tarfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.mrclam import DataError, _read_line_by_line, load_mrclam, read_table

HEADER = "# UTIAS Multi-Robot Cooperative Localization and Mapping Dataset\n# excerpt\n# format\n# columns\n"
T0 = 1248444175.0
DATASET6 = Path(__file__).resolve().parents[3] / ".." / "shared" / "data" / "MRCLAM_Dataset6.tar.xz"


def _write(folder: Path, name: str, rows: list[str]) -> None:
    (folder / name).write_text(HEADER + "".join(f"{row}\n" for row in rows))


def _excerpt(folder: Path) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    _write(folder, "Barcodes.dat", ["1 5", "2 14", "3 41", "4 32", "5 23", "6 63", "7 25"])
    _write(folder, "Landmark_Groundtruth.dat", ["6 0.588 -4.282 0.00004 0.00027", "7 0.682 -4.446 0.00005 0.00026"])
    for robot in range(1, 6):
        start = T0 + robot * 0.01
        _write(
            folder,
            f"Robot{robot}_Groundtruth.dat",
            [f"{start + k * 0.015:.3f} {robot}.0 {k * 0.01:.4f} 0.5" for k in range(4)],
        )
        _write(folder, f"Robot{robot}_Odometry.dat", [f"{start + k * 0.015:.3f}\t0.086\t-0.398" for k in range(3)])
        _write(
            folder,
            f"Robot{robot}_Measurement.dat",
            [
                f"{start + 0.04:.3f} 63 3.787 -0.257",
                f"{start + 0.02:.3f} 14 6.758 -0.005",
                f"{start + 0.05:.3f} 90 6.600 -0.022",
            ],
        )
    return folder


def test_an_excerpt_round_trips(tmp_path):
    data = load_mrclam(_excerpt(tmp_path / "set"))
    assert data.start_s == pytest.approx(T0 + 0.01) and data.landmarks.shape == (2, 5)
    log = data.robots[3]
    assert np.allclose(log.groundtruth[:, 0], 0.02 + np.arange(4) * 0.015) and np.allclose(log.groundtruth[:, 1], 3.0)
    assert np.allclose(log.odometry[0], [0.02, 0.086, -0.398])
    # barcode 14 is robot 2, 63 is landmark 6, 90 is unknown (skipped, counted); sorted by time
    assert np.allclose(log.sightings, [[0.04, 2, 6.758, -0.005], [0.06, 6, 3.787, -0.257]])
    assert log.unknown_barcodes == 1 and set(data.robots) == {1, 2, 3, 4, 5}


def test_the_archive_reads_like_the_directory(tmp_path):
    folder = _excerpt(tmp_path / "MRCLAM_Dataset0")
    archive = tmp_path / "set.tar.xz"
    with tarfile.open(archive, "w:xz") as tar:
        tar.add(folder, arcname=folder.name)
    a, b = load_mrclam(folder), load_mrclam(archive)
    assert a.start_s == b.start_s and all(
        np.array_equal(a.robots[r].sightings, b.robots[r].sightings) for r in a.robots
    )


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda f: (f / "Robot3_Odometry.dat").unlink(), "Robot3_Odometry.dat is missing"),
        (
            lambda f: _write(f, "Robot2_Measurement.dat", ["1248444175.1 14 abc 0.1"]),
            "Robot2_Measurement.dat line 5: expected 4 numbers, got '1248444175.1 14 abc 0.1'",
        ),
        (
            lambda f: _write(f, "Robot4_Odometry.dat", ["1248444175.1 0.1"]),
            "Robot4_Odometry.dat line 5: expected 3 numbers",
        ),
        (
            lambda f: _write(f, "Robot1_Groundtruth.dat", ["1248444175.2 1 2 3", "1248444175.1 1 2 3"]),
            "Robot1_Groundtruth.dat: time goes backwards at data row 2",
        ),
        (lambda f: _write(f, "Landmark_Groundtruth.dat", ["6 0.5 nan 0.1 0.1"]), "Landmark_Groundtruth.dat line 5"),
    ],
)
def test_every_malformed_case_is_one_clear_error(tmp_path, damage, message):
    folder = _excerpt(tmp_path / "set")
    damage(folder)
    with pytest.raises(DataError, match=message.replace("(", r"\(").replace(")", r"\)")):
        load_mrclam(folder)


def test_what_is_not_a_data_set_says_so(tmp_path):
    with pytest.raises(DataError, match="neither a data set directory nor"):
        load_mrclam(tmp_path / "nothing")
    (tmp_path / "broken.tar.xz").write_bytes(b"not xz")
    with pytest.raises(DataError, match="not a readable archive"):
        load_mrclam(tmp_path / "broken.tar.xz")


@pytest.mark.skipif(not DATASET6.exists(), reason="data set 6 is not on this machine (../shared/data)")
def test_data_set_6():
    data = load_mrclam(DATASET6)
    assert data.landmarks.shape == (15, 5) and round(data.duration_s) == 900
    assert [data.robots[r].unknown_barcodes for r in range(1, 6)] == [1, 0, 2, 3, 0]
    assert round(float(data.robots[1].groundtruth[-1, 0])) == 772  # robot 1's ground truth ends early


number = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64).map(repr),
    st.integers(-(10**12), 10**12).map(str),
    st.floats(-1e6, 1e6).map(lambda v: f"{v:.6e}"),
    st.sampled_from(["+1.5", "-0.0", "1e-320", "2.", ".5", "1_0", "nan", "inf", "-Infinity", "0x10", "1,5", "abc"]),
)
line = st.one_of(
    st.lists(number, min_size=1, max_size=4).flatmap(
        lambda fields: st.sampled_from([" ", "\t", "  ", " \t "]).map(lambda gap: gap.join(fields))
    ),
    st.sampled_from(["", "   ", "# a comment", "  # indented comment", "1 2 # trailing", "\u00a01 2", "1\x0c2 3"]),
)


@settings(max_examples=300)
@given(st.lists(line, max_size=12), st.sampled_from([2, 3]))
def test_a_table_reads_as_python_reads_each_line(tmp_path_factory, lines, width):
    """numpy's parser, taken where it reads every line, gives what Python's float gives line by line
    (the reader before it, kept for what numpy does not take), to the bit: the same table or the
    same error."""
    path = tmp_path_factory.mktemp("table") / "Robot1_Odometry.dat"
    path.write_text("\n".join(lines) + "\n")
    try:
        expected = _read_line_by_line(path, path.read_text().split("\n"), width)
    except DataError as refused:
        with pytest.raises(DataError, match=re.escape(str(refused))):
            read_table(path, width)
    else:
        got = read_table(path, width)
        assert got.shape == expected.shape and got.tobytes() == expected.tobytes()
