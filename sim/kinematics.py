"""Unicycle kinematics at constant altitude (cooperative-localization paper, motion model)."""

from __future__ import annotations

import numpy as np


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap radians to [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def unicycle_step(pose: np.ndarray, speed_mps: np.ndarray, yaw_rate_radps: np.ndarray, dt_s: float) -> np.ndarray:
    """Exact arc integration of ``[x, y, theta]`` for inputs held constant over ``dt_s``.

    pose (N, 3) in m, m, rad; speed_mps and yaw_rate_radps (N,). Returns the new poses (N, 3).
    x is north, y east, theta from north towards east.
    """
    theta = pose[:, 2]
    dtheta = yaw_rate_radps * dt_s
    # sin(dtheta/2)/(dtheta/2) is the chord factor of the arc; np.sinc(u) = sin(pi u)/(pi u).
    chord = speed_mps * dt_s * np.sinc(dtheta / (2.0 * np.pi))
    mid = theta + 0.5 * dtheta
    out = np.empty_like(pose)
    out[:, 0] = pose[:, 0] + chord * np.cos(mid)
    out[:, 1] = pose[:, 1] + chord * np.sin(mid)
    out[:, 2] = wrap_angle(theta + dtheta)
    return out
