"""The world's compass (bus.sensors.compass): the true heading plus white noise of the datasheet's
sigma (the filter is told the same sigma; the world adds nothing it does not know of: a magnetometer's
slowly varying declination error would be the next richer step). Pure."""

from __future__ import annotations

import numpy as np

from bus.angles import wrap_angle
from bus.sensors.compass import CompassSpec


def measure(pose: np.ndarray, spec: CompassSpec, rng: np.random.Generator) -> np.ndarray:
    """One row [heading rad, variance rad^2] of a vehicle at ``pose`` [x, y, theta]."""
    heading = wrap_angle(float(pose[2]) + spec.sigma_rad * float(rng.standard_normal()))
    return np.array([heading, spec.sigma_rad**2])
