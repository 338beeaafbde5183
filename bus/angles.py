"""Angle helpers shared by every package (bus is the only package they may all import)."""

from __future__ import annotations

import numpy as np


def wrap_angle(angle: float) -> float:
    """Wrap radians to [-pi, pi)."""
    return float((angle + np.pi) % (2.0 * np.pi) - np.pi)


def wrap_angles(angles: np.ndarray) -> np.ndarray:
    """Wrap radians (any shape) to [-pi, pi)."""
    return (np.asarray(angles, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi
