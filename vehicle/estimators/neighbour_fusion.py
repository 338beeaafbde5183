"""How a vehicle filter fuses a neighbour's fix (its own ranging to the neighbour, or the neighbour's
sighting of it relayed): by the vehicle's cooperative rule (vehicle.models.cooperative), its radio
noise learnt by IAE when that is on (only from believed neighbours), its persisting errors as states
when the filter keeps them, and fused only while the neighbour monitor believes the neighbour
(vehicle.estimators.trust). Pure."""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

from bus.topics import Topic
from vehicle.estimators.parts import ErrorStates, Say, Store
from vehicle.estimators.state import FilterState, tally_nis
from vehicle.estimators.trust import NeighbourTrust
from vehicle.models.cooperative import CooperativeRule
from vehicle.models.cooperative_fixes import CooperativeFix, SeenFix


@dataclass(frozen=True)
class NeighbourFusion:
    """A filter's way with neighbours' fixes: its cooperative ``rule``, fixes through sigma points of
    the pose (``unscented``), its neighbour monitor (``trust``, None: off)."""

    rule: CooperativeRule
    unscented: bool
    trust: NeighbourTrust | None

    def fuse(
        self,
        s: FilterState,
        store: Store,
        errors: ErrorStates | None,
        fix: CooperativeFix | SeenFix,
        gate: float,
        say: Say,
    ) -> bool:
        """One neighbour fix into ``s`` (already propagated to its stamp); True when it was fused. What
        the neighbour monitor finds is said with ``say``."""
        neighbour = fix.target_id if isinstance(fix, CooperativeFix) else fix.observer_id
        believed = s.neighbours.trusts(neighbour)
        adapt = None if s.iae is None or not believed else partial(s.iae.adapt, Topic.RANGING)
        model = None if errors is None else errors.of_fix(s, store, fix)  # may grow the state: first
        correction, result = self.rule.fuse(s.x, s.P, fix, gate, self.unscented, adapt, model)
        if self.trust is not None:
            believed = self.trust.judge(s, store, neighbour, fix, result, say)
        if not believed:
            s.counters.v2v_distrusted += 1
            return False
        if correction is not None:
            store.correct(s, correction)
        tally_nis(s, "robot" if isinstance(fix, CooperativeFix) else "seen", result, 2)
        return result.accepted
