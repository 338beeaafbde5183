"""What a misbehaving vehicle tells its neighbours (the ``lie`` and ``accuse`` faults, bus.faults):
its own bus layer applies the plan's active lies and accusations of it to each V2V broadcast before
it is signed and sent. Several active lies add their offsets and multiply their covariance scales;
the longest ``stale_s`` picks the past estimate they start from. Pure; reproducible in lockstep (a
lie depends on the sim time, the plan and the vehicle's own past estimates only)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from bus.estimate import PoseEstimate
from bus.faults import Accuse, Lie


def active_lies(faults: tuple, vehicle_id: int, t_s: float) -> list[Lie]:
    """The plan's lies of vehicle ``vehicle_id`` active at sim time ``t_s``."""
    return [f for f in faults if isinstance(f, Lie) and f.vehicle == vehicle_id and f.active(t_s)]


def false_accusations(faults: tuple, vehicle_id: int, t_s: float) -> frozenset[int]:
    """Whom the plan's active ``accuse`` faults of vehicle ``vehicle_id`` make it accuse at ``t_s``."""
    return frozenset(
        n for f in faults if isinstance(f, Accuse) and f.vehicle == vehicle_id and f.active(t_s) for n in f.names
    )


def longest_stale_s(faults: tuple, vehicle_id: int) -> float:
    """How far back any of the vehicle's lies replays its own past (0: none does)."""
    return max((f.stale_s for f in faults if isinstance(f, Lie) and f.vehicle == vehicle_id), default=0.0)


def told(estimate: PoseEstimate, lies: list[Lie], past: Sequence[PoseEstimate] = ()) -> PoseEstimate:
    """The estimate as the liar broadcasts it at its stamp: its pose of ``stale_s`` before (the latest
    of ``past``, oldest first, stamped at or before then; the oldest there is when none), stamped
    now, its position moved and its pose covariance scaled."""
    if not lies:
        return estimate
    stale_us = round(max(lie.stale_s for lie in lies) * 1e6)
    if stale_us and past:
        then = [p for p in past if p.stamp_us <= estimate.stamp_us - stale_us]
        estimate = dataclasses.replace(then[-1] if then else past[0], stamp_us=estimate.stamp_us)
    t_s = estimate.stamp_us / 1e6
    pose = np.array(estimate.pose, dtype=float)
    scale = 1.0
    for lie in lies:
        pose[:2] += lie.offset_at(t_s)
        scale *= lie.cov_scale
    return dataclasses.replace(estimate, pose=pose, pose_cov=np.asarray(estimate.pose_cov) * scale)
