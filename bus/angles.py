"""Angle helpers shared by every package (bus is the only package they may all import)."""

from __future__ import annotations

import numpy as np


def wrap_angle(angle: float) -> float:
    """Wrap radians to [-pi, pi)."""
    return float((angle + np.pi) % (2.0 * np.pi) - np.pi)
