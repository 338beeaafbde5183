"""How a GNSS fix observes the vehicle state: white noise on [x, y] (``WhiteGnss``), or the
receiver's time-correlated error as two Gauss-Markov states after the pose (``GnssWithErrorStates``,
vehicle.models.gnss_error: fix = [x, y] + e + white). Each also sets up the state a prior starts
from. Pure."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vehicle.models.gnss_error import GnssErrorModel, aligned_covariance

GNSS_STATES_H = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0]])  # d fix / d [x, y, e_x, e_y]


@dataclass(frozen=True)
class Observed:
    """What a fix should read (2,), the states it depends on (``idx``) with its H (2, len(idx)), and
    the noise (2, 2) of its white part."""

    predicted: np.ndarray
    idx: list[int]
    H: np.ndarray
    R: np.ndarray

    def full_H(self, n: int) -> np.ndarray:
        """H (2, n) over a state of n entries."""
        H = np.zeros((2, n))
        H[:, self.idx] = self.H
        return H


class WhiteGnss:
    """fix = [x, y] + white noise with the receiver's reported covariance. State [x, y, theta, b] (4,)."""

    error: GnssErrorModel | None = None
    base_dim = 4

    def initial(self, pose: np.ndarray, covariance: np.ndarray, from_fixes: bool) -> tuple[np.ndarray, np.ndarray]:
        """The state (4,) and covariance (4, 4) at ``pose`` (3,) with ``covariance`` (3, 3); the gyro
        bias's variance is the filter's to set."""
        x = np.zeros(4)
        x[:3] = pose
        P = np.zeros((4, 4))
        P[:3, :3] = covariance
        return x, P

    def observe(self, x: np.ndarray, reported_cov_m2: np.ndarray) -> Observed:
        return Observed(x[:2], [0, 1], np.eye(2), reported_cov_m2)


class GnssWithErrorStates:
    """fix = [x, y] + e + white, e the two Gauss-Markov states at 4 and 5 (vehicle.models.gnss_error);
    the white part is the datasheet's share of the reported covariance. State (6,)."""

    base_dim = 6

    def __init__(self, error: GnssErrorModel) -> None:
        self.error = error

    def initial(self, pose: np.ndarray, covariance: np.ndarray, from_fixes: bool) -> tuple[np.ndarray, np.ndarray]:
        """As :meth:`WhiteGnss.initial`, with e = 0 at its stationary spread; tied to the position when
        the pose was aligned ``from_fixes`` (they shared e)."""
        x = np.zeros(6)
        x[:3] = pose
        if from_fixes:
            return x, aligned_covariance(covariance, self.error)
        P = np.diag([0.0, 0.0, 0.0, 0.0] + [self.error.variance_m2] * 2)
        P[:3, :3] = covariance
        return x, P

    def observe(self, x: np.ndarray, reported_cov_m2: np.ndarray) -> Observed:
        return Observed(x[:2] + x[4:6], [0, 1, 4, 5], GNSS_STATES_H, self.error.white(reported_cov_m2))


def gnss_model(error: GnssErrorModel | None) -> WhiteGnss | GnssWithErrorStates:
    """The GNSS model for a datasheet's correlated error (None: white)."""
    return WhiteGnss() if error is None else GnssWithErrorStates(error)
