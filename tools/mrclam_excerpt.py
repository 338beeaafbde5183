"""Cut an excerpt of an MRCLAM data set, line by line from its published files: ``Barcodes.dat``
and ``Landmark_Groundtruth.dat`` whole, every robot's ``Groundtruth``, ``Odometry`` and
``Measurement`` rows stamped from START to END seconds after the data set's first stamp, headers
kept; written as DEST (a directory) and DEST.tar.xz. The tests' data (tests/data/README.md) were
cut this way.

    python tools/mrclam_excerpt.py DATASET_DIR START END DEST
"""

from __future__ import annotations

import sys
import tarfile
from pathlib import Path

KINDS = ("Groundtruth", "Odometry", "Measurement")


def first_stamp(folder: Path) -> float:
    """The data set's first stamp (s, Unix): the earliest row of any robot file."""
    stamps = []
    for path in folder.glob("Robot*_*.dat"):
        if path.stem.split("_", 1)[1] in KINDS:
            rows = [line for line in path.read_text().splitlines() if line.strip() and not line.startswith("#")]
            stamps.append(float(rows[0].split()[0]))
    return min(stamps)


def cut(folder: Path, start_s: float, end_s: float, dest: Path) -> Path:
    t0 = first_stamp(folder)
    dest.mkdir(parents=True, exist_ok=True)
    for name in ("Barcodes.dat", "Landmark_Groundtruth.dat"):
        (dest / name).write_bytes((folder / name).read_bytes())
    for path in sorted(folder.glob("Robot*_*.dat")):
        if path.stem.split("_", 1)[1] not in KINDS:
            continue
        kept = []
        for line in path.read_bytes().decode().splitlines(keepends=True):  # the published line endings kept
            if line.startswith("#") or not line.strip():
                kept.append(line)
            elif t0 + start_s <= float(line.split()[0]) <= t0 + end_s:
                kept.append(line)
        (dest / path.name).write_bytes("".join(kept).encode())
    archive = dest.with_name(dest.name + ".tar.xz")
    with tarfile.open(archive, "w:xz") as tar:
        tar.add(dest, arcname=dest.name)
    return archive


if __name__ == "__main__":
    source, start, end, target = sys.argv[1:5]
    print(cut(Path(source), float(start), float(end), Path(target)))
