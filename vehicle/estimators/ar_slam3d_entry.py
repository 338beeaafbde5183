"""Which of a frame's unpaired points enter the 3-D AR-EKF-SLAM map (vehicle.estimators.ar_slam3d),
and which wait as candidates. Pure: the back end places the points that enter.

``first`` (the paper's): a point enters on the sighting that finds it within R. ``second`` (the
default): that sighting makes it a candidate, and the next sighting of it (by id, or the nearest
candidate within the gate) makes it enter, whatever that sighting's own depth; a candidate not seen
again within ``CANDIDATE_FRAMES`` frames is let go (docs/ar-slam.md, Consistency).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

CANDIDATE_FRAMES = 5
Entry = Literal["first", "second"]


@dataclass(frozen=True, eq=False)
class Candidate:
    """A point seen once within R: its id (-1 unidentified), where the sighting put it in the fixed frame
    (3,) and that position's covariance (3, 3) (own position's and the sighting's), and the frame."""

    ident: int
    xyz: np.ndarray
    cov: np.ndarray
    frame: int


@dataclass(frozen=True)
class Unpaired:
    """A frame's points that paired with no landmark: their indices in the frame (m,), where each lies in
    the fixed frame (m, 3) with that position's covariance (m, 3, 3), their ids (m,) (-1 unidentified),
    whether the frame is identified (ids decide a second sighting, not the gate) and which lie within R
    (m,)."""

    index: np.ndarray
    xyz: np.ndarray
    cov: np.ndarray
    ident: np.ndarray
    identified: bool
    within: np.ndarray


def entering(
    candidates: list[Candidate], points: Unpaired, frame: int, gate: float, entry: Entry
) -> tuple[dict[int, int], list[Candidate]]:
    """The points that enter the map now, {index in the frame: id} in the frame's order, and the
    candidates that remain after frame number ``frame`` (module docstring; ``gate``: chi-square, 3 dof)."""
    if entry == "first":
        return {int(points.index[m]): int(points.ident[m]) for m in np.flatnonzero(points.within)}, candidates
    seconds = seen_again(candidates, points, gate)
    taken = {id(c) for c in seconds.values()}
    remaining = [c for c in candidates if id(c) not in taken and frame - c.frame < CANDIDATE_FRAMES]
    remaining += [
        Candidate(int(points.ident[m]), points.xyz[m], points.cov[m], frame)
        for m in np.flatnonzero(points.within)
        if m not in seconds
    ]
    return {int(points.index[m]): c.ident for m, c in seconds.items()}, remaining


def seen_again(candidates: list[Candidate], points: Unpaired, gate: float) -> dict[int, Candidate]:
    """Which points (their rows in ``points``) are candidates seen again: by id, or each the nearest
    candidate within the gate (one candidate per point)."""
    out: dict[int, Candidate] = {}
    free = list(candidates)
    for m in range(len(points.index)):
        if points.identified:
            match = next((c for c in free if c.ident == int(points.ident[m])), None)
        else:
            xyz, cov = points.xyz[m], points.cov[m]
            d2 = [float((xyz - c.xyz) @ np.linalg.solve(cov + c.cov, xyz - c.xyz)) for c in free]
            match = free[int(np.argmin(d2))] if d2 and min(d2) <= gate else None
        if match is not None:
            out[m] = match
            free = [c for c in free if c is not match]
    return out
