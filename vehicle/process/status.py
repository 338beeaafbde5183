"""A vehicle's status (``VehicleStatus``, on its status key every ``status_period_s`` and at the end):
its loop's statistics, what its estimator and fusion horizon counted, its feeds' losses, its V2V
epochs' missing broadcasts and the input it rejected, read off the node in one place."""

from __future__ import annotations

from typing import Protocol

from bus import messages as m
from bus.rejections import Rejections
from vehicle.estimators.filter import Filter
from vehicle.process.fusion import FusionHorizon
from vehicle.process.inbound import Inbound
from vehicle.process.loop_stats import LoopStats
from vehicle.process.sequence import SequenceTracker
from vehicle.process.v2v import V2V


class Reporting(Protocol):
    """What a status is read off (a vehicle.process.node.VehicleNode)."""

    vehicle_id: int
    stats: LoopStats
    estimator: Filter
    fusion: FusionHorizon
    rejections: Rejections
    sequences: SequenceTracker
    v2v: V2V
    inbound: Inbound
    reset_counter: int
    loop_priority: int


def vehicle_status(node: Reporting, t_us: int, *, final: bool = False) -> m.VehicleStatus:
    """The status of ``node`` after its cycle at ``t_us`` (``final``: the run's last)."""
    c, f = node.estimator.counters, node.fusion.counters
    return m.VehicleStatus(
        vehicle_id=node.vehicle_id,
        stamp_us=t_us,
        cycles=node.stats.cycles,
        overruns=node.stats.overruns,
        jitter_p99_us=node.stats.jitter_p99_us(),
        cycle_p99_us=node.stats.cycle_p99_us(),
        dropped_stale=c.stale + f.dropped_stale,
        rejected_gnss=c.gnss_rejected,
        decode_errors=node.rejections.total,
        reset_counter=node.reset_counter % 256,
        duplicates=f.duplicates,
        samples_lost=node.sequences.lost,
        late_fused=f.late_fused,
        v2v_fused=c.v2v_fused,
        v2v_missing=node.v2v.missing,
        rejected=node.rejections.as_counts(),
        replays=f.replays,
        final=final,
        landmarks=c.landmarks,
        landmarks_updated=c.landmarks_updated,
        frames_used=c.frames_used,
        nis=c.nis.values,
        loop_priority=node.loop_priority,
        v2v_received=node.inbound.v2v_received,
    )
