"""The AR-EKF-SLAM paper's front end (SUSAN + NCC + RANSAC on F) against SIFT and ORB on the same
rendered frames of a flight over relief (experiments.front_ends): keypoints per frame, repeatability,
correct matches per frame pair and their share, detection time per frame and matching time per pair.
Context rows (the issue asks for the comparison, not a bound)."""

from __future__ import annotations

from bench.common import Row
from experiments.front_ends import compare, fly

METRICS = (
    ("keypoints", "keypoints per frame", ""),
    ("repeatability", "repeatability", ""),
    ("correct_matches", "correct matches per pair", ""),
    ("correct_share", "share of kept matches correct", ""),
    ("detect_ms", "detection per frame", "ms"),
    ("match_ms", "matching + RANSAC per pair", "ms"),
)


def run(quick: bool = False) -> list[Row]:
    flight = fly(seed=0, frames=6 if quick else 20, scale=1.0)  # the paper's 640 x 480
    width, height = flight.camera.size
    case = f"{len(flight.frames)} frames {width} x {height} over relief"
    rows = []
    for front_end, measured in compare(flight).items():
        for key, metric, unit in METRICS:
            rows.append(Row("front ends", f"{front_end}, {case}", metric, round(measured[key], 3), unit, "-", None))
    return rows
