"""Which keypoints of a camera frame are which mapped landmarks (vehicle.estimators.vision_map):

- ``by_descriptor``: descriptor match with the ratio test among the landmarks in view, kept when the
  pairs agree on one rigid motion (RANSAC, ``vehicle.association.descriptors``);
- ``by_geometry``: a data-association method of ``vehicle.association`` (nn, jcbb, aco) on the
  range-bearing innovations, among each visible landmark's descriptor shortlist.

Each returns pairs (keypoint index, row of ``visible``). Pure but for the seeded generator of a
randomized method (seeded by the vehicle and the frame, so that a replayed frame is associated alike)."""

from __future__ import annotations

import numpy as np

from vehicle.association import descriptors as matching
from vehicle.association.methods import METHODS
from vehicle.association.problem import Problem, problem
from vehicle.estimators.state import FilterState
from vehicle.models import landmarks as slam
from vehicle.vision import features

CONSENSUS_M = 0.3  # matches must agree on one rigid motion within this [m]
SHORTLIST = 3  # geometric association: each landmark's nearest keypoints by descriptor
LANDMARK_GATE_P = 0.999  # Mahalanobis gate on each landmark update (and on an association's pairs)
Pairs = list[tuple[int, int]]


def by_descriptor(
    found: features.Features,
    z: np.ndarray,
    mapped: np.ndarray,
    visible: np.ndarray,
    descriptors: np.ndarray,
    pose: np.ndarray,
    norm: int,
) -> Pairs:
    """Descriptor pairs of keypoints (``z``: [range, bearing] (k, 2)) with the ``visible`` rows of the
    ``mapped`` landmarks (m, 2) that agree on one rigid motion from ``pose`` (3,)."""
    pairs = matching.match(found.descriptors, descriptors[visible], norm) if len(visible) else []
    if pairs:
        seen = np.array([z[i] for i, _ in pairs])
        measured = np.stack([seen[:, 0] * np.cos(seen[:, 1]), seen[:, 0] * np.sin(seen[:, 1])], axis=1)
        predicted = matching.to_body(mapped[[visible[row] for _, row in pairs]], pose)
        agree = matching.rigidly_consistent(predicted, measured, CONSENSUS_M)
        pairs = [pair for pair, ok in zip(pairs, agree.tolist()) if ok]
    return pairs


def by_geometry(
    method: str,
    found: features.Features,
    z: np.ndarray,
    R: np.ndarray,
    visible: np.ndarray,
    s: FilterState,
    head_dim: int,
    norm: int,
    seed: list[int],
) -> tuple[Pairs, tuple[Problem, np.ndarray] | None]:
    """Pairs by ``method`` among each visible landmark's descriptor shortlist, and the association
    problem with its assignment (None when there was nothing to associate)."""
    if not len(visible) or s.landmarks.descriptors is None:
        return [], None
    shortlisted = matching.shortlist(found.descriptors, s.landmarks.descriptors[visible], norm, SHORTLIST)
    observations = sorted({i for i, _ in shortlisted})
    if not observations:
        return [], None
    column = {i: a for a, i in enumerate(observations)}
    allowed = np.zeros((len(observations), len(visible)), dtype=bool)
    for i, row in shortlisted:
        allowed[column[i], row] = True
    predicted, C = predictions(s, head_dim, visible)
    p = problem(z[observations], R[observations], predicted, C, allowed=allowed, gate_probability=LANDMARK_GATE_P)
    assignment = METHODS[method](p, np.random.default_rng(seed))
    pairs = [(observations[a], int(row)) for a, row in enumerate(assignment.tolist()) if row >= 0]
    return pairs, (p, assignment)


def predictions(s: FilterState, head_dim: int, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Predicted observations (m, 2) of mapped landmarks ``rows`` and their joint covariance
    C = H P H^T (2m, 2m) (Jacobians at the current estimate)."""
    m = len(rows)
    predicted = np.zeros((m, 2))
    H = np.zeros((2 * m, 3 + 2 * m))
    for a, j in enumerate(rows.tolist()):
        predicted[a], H[2 * a : 2 * a + 2, :3], H[2 * a : 2 * a + 2, 3 + 2 * a : 5 + 2 * a] = slam.observe(
            s.x, head_dim, j
        )
    columns = np.concatenate([[0, 1, 2], (head_dim + 2 * rows[:, None] + np.arange(2)).ravel()])
    return predicted, H @ s.P[np.ix_(columns, columns)] @ H.T
