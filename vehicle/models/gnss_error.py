"""The time-correlated part of a GNSS receiver's error as two filter states (pure maths).

A receiver's horizontal error is not white: multipath, ionosphere and orbit errors wander over tens of
seconds. A filter that averages 5 fixes a second as if independent becomes over-confident by the
ratio of the correlation time to the fix period. The datasheet's total sigma is split into a white
part and a first-order Gauss-Markov part per axis (Brown & Hwang, Introduction to Random Signals and
Applied Kalman Filtering, 4th ed., sec. 3.9 and 9.2), and the filter estimates the latter:

    e(t + dt) = phi e(t) + w,  phi = exp(-dt / tau),  var(w) = sigma_c^2 (1 - phi^2)      (stationary)
    fix = [x, y] + e + v,      var(v) = (1 - sigma_c^2 / sigma^2) R_reported              (white share)

The receiver's reported covariance is split in the datasheet's proportion, so a receiver that
reports a degraded fix keeps the same share of white noise. States are appended to the vehicle
state after [x, y, theta, gyro_bias]: indices 4 and 5 (m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bus.config import SensorSpec

FIRST = 4  # index of the first GNSS error state in the vehicle state
STATES = 2  # east and north error (m)


@dataclass(frozen=True)
class GnssErrorModel:
    """The datasheet's correlated GNSS error: stationary sigma (m, per axis) and correlation time (s),
    next to the receiver's total sigma (m)."""

    sigma_m: float
    tau_s: float
    total_sigma_m: float

    @classmethod
    def from_spec(cls, spec: SensorSpec) -> GnssErrorModel | None:
        """The model the datasheet asks for; None when it calls the GNSS error white."""
        if spec.gnss_correlated_sigma_m <= 0.0:
            return None
        return cls(spec.gnss_correlated_sigma_m, spec.gnss_correlation_s, spec.gnss_sigma_m)

    @property
    def variance_m2(self) -> float:
        return self.sigma_m**2

    def transition(self, dt_s: float) -> tuple[float, float]:
        """phi and the process noise variance (m^2, per axis) over dt_s."""
        phi = math.exp(-dt_s / self.tau_s)
        return phi, self.variance_m2 * (1.0 - phi * phi)

    def white(self, reported_cov_m2: np.ndarray) -> np.ndarray:
        """The white share (2, 2) of a fix's reported covariance (2, 2)."""
        return reported_cov_m2 * (1.0 - self.variance_m2 / self.total_sigma_m**2)


def augment_motion(F: np.ndarray, Q: np.ndarray, model: GnssErrorModel, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The vehicle motion's F (4, 4) and Q (4, 4) grown to (6, 6) with the error states' decay."""
    phi, q = model.transition(dt_s)
    F6, Q6 = np.zeros((FIRST + STATES, FIRST + STATES)), np.zeros((FIRST + STATES, FIRST + STATES))
    F6[:FIRST, :FIRST], Q6[:FIRST, :FIRST] = F, Q
    F6[FIRST:, FIRST:] = phi * np.eye(STATES)
    Q6[FIRST:, FIRST:] = q * np.eye(STATES)
    return F6, Q6


def observation(n: int) -> np.ndarray:
    """H (2, n) of a fix on a state with the error states: position plus error."""
    H = np.zeros((2, n))
    H[:, :2] = np.eye(2)
    H[:, FIRST : FIRST + STATES] = np.eye(2)
    return H


def aligned_covariance(pose_cov: np.ndarray, model: GnssErrorModel) -> np.ndarray:
    """Covariance (6, 6) of a state aligned from fixes (pose covariance (3, 3) from the alignment):
    the position then carries the error the fixes shared, e = 0 is as uncertain as e itself and the
    two are anti-correlated (position error = e + white average, error-state error = -e)."""
    P = np.zeros((FIRST + STATES, FIRST + STATES))
    P[:3, :3] = pose_cov
    s2 = model.variance_m2 * np.eye(2)
    P[:2, :2] += s2
    P[FIRST:, FIRST:] = s2
    P[:2, FIRST:] = P[FIRST:, :2] = -s2
    return P
