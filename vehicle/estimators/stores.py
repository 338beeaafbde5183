"""Where a filter's mean x (n,) and covariance P (n, n) live, and how they change: each store applies
a motion step, a gated update, a cooperative correction, and adds, drops or decorrelates states.

- ``DenseStore``: plain arrays, replaced by each change (the vehicle filters, n below ~40);
- ``InPlaceStore``: a SLAM map's x and P changed in their own memory, O(n) for the gain and O(n^2)
  flops with no n x n temporary (vehicle.models.landmarks); the motion moves only the head of the
  state (the map stands still);
- the centralized reference's joint block (vehicle.estimators.centralized.JointBlock): one vehicle's block of
  a joint state, so every change lands on the cross-covariances too.

A store only changes the ``FilterState`` it is handed. Pure."""

from __future__ import annotations

import numpy as np

from bus.angles import wrap_angle
from vehicle.estimators.state import FilterState
from vehicle.models import added_states
from vehicle.models import landmarks as slam
from vehicle.models.cooperative import Correction, apply_correction
from vehicle.models.kalman import UpdateResult, gated_update


class DenseStore:
    """x and P as plain arrays (module docstring)."""

    dense = True  # the closed-form 4-state prediction may replace them

    def move(self, s: FilterState, F: np.ndarray, Q: np.ndarray, x_next: np.ndarray) -> None:
        """P <- F P F^T + Q, x <- x_next; F and Q over the whole state."""
        P = F @ s.P @ F.T + Q
        s.P = 0.5 * (P + P.T)
        s.x = x_next

    def update(
        self, s: FilterState, y: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float, idx: list[int] | None = None
    ) -> UpdateResult:
        """One gated update (Joseph form) with innovation y (m,), H over the states ``idx`` (all when
        None), noise R (m, m); the heading wrapped."""
        if idx is not None:
            full = np.zeros((len(y), len(s.x)))
            full[:, idx] = H
            H = full
        s.x, s.P, result = gated_update(s.x, s.P, y, H, R, gate)
        s.x[2] = wrap_angle(s.x[2])
        return result

    def correct(self, s: FilterState, correction: Correction) -> None:
        s.x, s.P = apply_correction(s.x, s.P, correction)

    def append(self, s: FilterState, variances: np.ndarray) -> None:
        """States at 0 with these variances after the last one, uncorrelated."""
        s.x, s.P = added_states.append_states(s.x, s.P, variances)

    def drop(self, s: FilterState, indices: list[int]) -> None:
        """The states at ``indices`` marginalized out."""
        s.x, s.P = added_states.drop_states(s.x, s.P, indices)

    def set_spread(self, s: FilterState, indices: list[int], variances: np.ndarray) -> None:
        """The states at ``indices`` get these variances, uncorrelated with every other state."""
        added_states.set_spread(s.P, indices, variances)

    def inflate(self, s: FilterState, indices: list[int], variances: np.ndarray) -> None:
        """The states at ``indices`` get these variances added (process noise: correlations kept)."""
        s.P[indices, indices] += variances


class InPlaceStore(DenseStore):
    """A SLAM map's x and P, changed in place (module docstring); adding and dropping states still
    reallocate (once per camera frame, not per measurement)."""

    dense = False

    def move(self, s: FilterState, F: np.ndarray, Q: np.ndarray, x_next: np.ndarray) -> None:
        """The head of the state (len(x_next)) moves by F, Q; the rest stands still."""
        slam.predict_pose(s.x, s.P, F, Q, x_next)

    def update(
        self, s: FilterState, y: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float, idx: list[int] | None = None
    ) -> UpdateResult:
        """A two-dimensional measurement y (2,) of the states ``idx`` through H (2, len(idx))."""
        return slam.update_in_place(s.x, s.P, list(range(len(s.x))) if idx is None else idx, H, y, R, gate)

    def correct(self, s: FilterState, correction: Correction) -> None:
        slam.apply_correction_in_place(s.x, s.P, correction)
