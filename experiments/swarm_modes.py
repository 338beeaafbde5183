"""A swarm's pose errors split into what the whole swarm shares and what is left, each judged by the
covariance a joint filter claims for it (the centralized reference keeps the cross-covariances that
make this possible).

The common mode is the swarm's mean pose error: the centroid's position (2 dof) and the mean heading
(1 dof), c = A e with A = (1/N) [I_3 ... I_3] (3, 3N) and covariance A P A^T. The relative part is
what is left, r = (I - 1_N (x) A) e (3N,) with covariance D P D^T; it has 3N - 3 degrees of freedom
(its covariance is singular along the common mode), so its NEES uses the pseudo-inverse over the
nonzero eigenvalues. A consistent filter has each part's NEES chi-square with its dof; a swarm whose
absolute frame is held by a few GNSS receivers can be honest about one part and not the other.
Pure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bus.angles import wrap_angles


@dataclass(frozen=True)
class SwarmModes:
    """The parts of one instant's joint pose error: NEES of the centroid (2 dof), of the mean heading
    (1 dof) and of the relative part (``relative_dof``); the centroid's error and claimed sigma (m,
    root of the covariance's trace), the mean heading's error and claimed sigma (rad)."""

    centroid_nees: float
    heading_nees: float
    relative_nees: float
    relative_dof: int
    centroid_error_m: float
    centroid_sigma_m: float
    heading_error_rad: float
    heading_sigma_rad: float


def swarm_modes(errors: np.ndarray, covariance: np.ndarray) -> SwarmModes:
    """Split pose errors ``errors`` (N, 3) [m, m, rad] of N vehicles, with their joint covariance
    ``covariance`` (3N, 3N) in the same order, into the common mode and the relative part (module
    docstring). Headings are wrapped before averaging."""
    n = errors.shape[0]
    e = np.array(errors, dtype=float)
    e[:, 2] = wrap_angles(e[:, 2])
    e = e.reshape(-1)
    mean = np.kron(np.ones((1, n)), np.eye(3)) / n  # A (3, 3N)
    common, common_cov = mean @ e, mean @ covariance @ mean.T
    rest = np.eye(3 * n) - np.kron(np.ones((n, 1)), mean)  # D (3N, 3N)
    relative, relative_cov = rest @ e, rest @ covariance @ rest.T
    values, vectors = np.linalg.eigh(0.5 * (relative_cov + relative_cov.T))
    kept = values > 1e-9 * values.max()
    return SwarmModes(
        centroid_nees=float(common[:2] @ np.linalg.solve(common_cov[:2, :2], common[:2])),
        heading_nees=float(common[2] ** 2 / common_cov[2, 2]),
        relative_nees=float(np.sum((vectors[:, kept].T @ relative) ** 2 / values[kept])),
        relative_dof=int(kept.sum()),
        centroid_error_m=float(np.hypot(common[0], common[1])),
        centroid_sigma_m=float(np.sqrt(common_cov[0, 0] + common_cov[1, 1])),
        heading_error_rad=float(common[2]),
        heading_sigma_rad=float(np.sqrt(common_cov[2, 2])),
    )
