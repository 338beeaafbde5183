"""What a lying vehicle tells its neighbours (the ``lie`` fault, bus.faults.Lie): its own bus layer
applies the plan's active lies about it to each V2V broadcast before it is signed and sent. Several
active lies add their offsets and multiply their covariance scales. Pure; reproducible in lockstep
(a lie depends on the sim time and the plan only)."""

from __future__ import annotations

import dataclasses

import numpy as np

from bus.estimate import PoseEstimate
from bus.faults import Lie


def active_lies(faults: tuple, vehicle_id: int, t_s: float) -> list[Lie]:
    """The plan's lies of vehicle ``vehicle_id`` active at sim time ``t_s``."""
    return [f for f in faults if isinstance(f, Lie) and f.vehicle == vehicle_id and f.active(t_s)]


def told(estimate: PoseEstimate, lies: list[Lie]) -> PoseEstimate:
    """The estimate as the liar broadcasts it at its stamp: position moved, pose covariance scaled."""
    if not lies:
        return estimate
    t_s = estimate.stamp_us / 1e6
    pose = np.array(estimate.pose, dtype=float)
    scale = 1.0
    for lie in lies:
        pose[:2] += lie.offset_at(t_s)
        scale *= lie.cov_scale
    return dataclasses.replace(estimate, pose=pose, pose_cov=np.asarray(estimate.pose_cov) * scale)
