"""What a lockstep tick and its cycles wait for before they run (vehicle.process.loops): the tick's sensor
batch and the V2V broadcasts the neighbours had sent by their last acknowledgements (``ready``), and
before a cycle, the broadcasts its maturing ranging measurements pair with (``unheard_neighbours``);
what was waited for in vain is written off, so that one lost frame costs one wait."""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable

from bus import messages as m
from bus.keys import KeySpace
from vehicle.process.inbound import Inbound
from vehicle.process.v2v import V2V
from vehicle.process.world_watch import WorldWatch

TICK_SPANS = 256  # lockstep ticks remembered for the V2V waits (a fix waits one V2V latency: 5 ticks of 20 ms)


class LockstepWaits:
    """One vehicle's waits, over what its bus layer has filed (``inbound``), its ranging measurements
    (``v2v``) and its watch on the other processes (``world_watch``)."""

    def __init__(
        self, vehicle_id: int, cooperative: bool, inbound: Inbound, v2v: V2V, world_watch: WorldWatch, keys: KeySpace
    ) -> None:
        self.vehicle_id, self.cooperative, self.keys = vehicle_id, cooperative, keys
        self._v2v_keys: dict[int, tuple[str, str]] = {}  # sender -> the keys its frames to this vehicle come on
        self.inbound, self.v2v, self.world_watch = inbound, v2v, world_watch
        self.first_tick: m.ClockTick | None = None
        self.finished_us: int | None = None  # the stamp of the last tick acknowledged
        self.heard_floor: dict[int, int] = {}  # broadcasts counted as heard: sent before the first tick, or written off
        # (previous tick's stamp, stamp, running) of the ticks cycled, for the V2V waits
        self.tick_spans: deque[tuple[int, int, frozenset[int]]] = deque(maxlen=TICK_SPANS)

    def start(self, tick: m.ClockTick) -> None:
        """The vehicle's first tick: a vehicle that joins a running swarm (a restart) does not wait for
        what was published before it, which either arrived or never will."""
        self.first_tick = tick
        if tick.tick > 0:
            self.heard_floor = {i + 1: n for i, n in enumerate(tick.v2v_published)}

    def ready(self, tick: m.ClockTick) -> bool:
        """Lockstep: the tick's sensor batch has arrived, and every V2V broadcast the neighbours had
        sent by their last acknowledgements (zenoh orders samples within a key, not across keys). The
        world sends one batch per tick, in order on the vehicle's key, so the batches refused
        (malformed, or too large) since the newest good one were the ticks after it: a tick whose
        batch was refused runs without it at once instead of waiting for a batch not on its way."""
        joined_late = tick is self.first_tick and tick.tick > 0  # a restart: earlier batches are gone
        covered = self.inbound.received_tick + self.inbound.refused_since
        if covered < tick.tick and not joined_late:
            return False
        return not self.unheard_senders(tick)

    def unheard_senders(self, tick: m.ClockTick) -> list[int]:
        """The neighbours of whose V2V broadcasts, sent by their last acknowledgements before
        ``tick``, some have not arrived yet (``ready``'s rule)."""
        return list(self._shortfall(tick)) if self.cooperative else []

    def _shortfall(self, tick: m.ClockTick) -> dict[int, int]:
        """Neighbour -> how many of the V2V broadcasts it had sent by its last acknowledgement before
        ``tick`` have not arrived (only those short of some)."""
        heard, floor, short = self.inbound.heard, self.heard_floor, {}
        for j, n in enumerate(tick.v2v_published, start=1):
            missing = n - heard.get(j, 0) - floor.get(j, 0)
            if j != self.vehicle_id and missing > 0:
                short[j] = missing
        return short

    def senders_by_key(self, senders: Iterable[int]) -> dict[str, int]:
        """The keys the V2V frames of ``senders`` reach this vehicle on (broadcast and addressed),
        each to its sender: what wakes a loop waiting for them (bus.mailbox)."""
        known, by_key = self._v2v_keys, {}
        for j in senders:
            if j not in known:
                known[j] = (self.keys.v2v(j), self.keys.v2v_to(j, self.vehicle_id))
            broadcast, addressed = known[j]
            by_key[broadcast] = by_key[addressed] = j
        return by_key

    def unheard_neighbours(self, tick: m.ClockTick, t_us: int) -> list[tuple[int, int]]:
        """Lockstep, before the cycle at ``t_us``: (neighbour, stamp) of the broadcasts its maturing
        ranging measurements pair with that have not arrived yet, from neighbours that ran every
        cycle of the tick the stamp falls in (``running`` of that tick). Zenoh orders one
        neighbour's frames to this vehicle, so having heard a later stamp means the wanted one came
        (or the neighbour, which sends at every epoch to whoever ranges it, had none to send). Lets
        a tick span several V2V latencies, and each frame go only to the vehicles that range its
        sender, with what a cycle fuses still independent of the bus's timing. Not waited for: the
        stamps up to this vehicle's first tick (a restart: what was sent before it may be lost), and
        a neighbour that died meanwhile (its liveliness token is gone)."""
        if not self.cooperative or self.finished_us is None:
            return []
        spans = self.tick_spans
        if not spans or spans[-1][1] != tick.stamp_us:
            spans.append((self.finished_us, tick.stamp_us, frozenset(tick.running)))
        return self.waited_for(self.still_unheard([(j, s) for j, s in self.v2v.awaited(t_us) if _ran(spans, j, s)]))

    def still_unheard(self, awaited: list[tuple[int, int]]) -> list[tuple[int, int]]:
        """Of ``awaited`` (``unheard_neighbours`` of one cycle), the broadcasts not heard yet, their
        senders departed or not (a departed neighbour may come back while the cycle waits)."""
        until = self.inbound.heard_until
        return [(j, s) for j, s in awaited if until.get(j, -1) < s]

    def waited_for(self, unheard: list[tuple[int, int]]) -> list[tuple[int, int]]:
        """Of ``unheard``, those whose senders are alive (``unheard_neighbours``'s rule)."""
        departed = self.world_watch.departed
        return [(j, s) for j, s in unheard if j not in departed]

    def write_off_unheard(self, unheard: list[tuple[int, int]]) -> None:
        """After the wait for them timed out: count those broadcasts as heard (they are missing)."""
        until = self.inbound.heard_until
        for j, s in unheard:
            until[j] = max(until.get(j, -1), s)

    def missing_inputs(self, tick: m.ClockTick) -> str:
        """What ``ready`` still waits for, in words (for the log)."""
        parts = []
        if self.inbound.received_tick < tick.tick:
            parts.append(f"sensor batch {tick.tick} (latest {self.inbound.received_tick})")
        published = tick.v2v_published
        parts += [
            f"V2V of vehicle {j}: {published[j - 1] - short} of {published[j - 1]}"
            for j, short in self._shortfall(tick).items()
        ]
        return "; ".join(parts)

    def write_off_missing(self, tick: m.ClockTick) -> None:
        """After the wait for ``tick`` timed out: V2V broadcasts that never came are written off, so
        one lost frame costs one wait, not one per later tick."""
        for j, short in self._shortfall(tick).items():
            self.heard_floor[j] = self.heard_floor.get(j, 0) + short


def _ran(spans: deque[tuple[int, int, frozenset[int]]], neighbour: int, stamp_us: int) -> bool:
    """Whether ``neighbour`` ran every cycle of the tick (span) that ``stamp_us`` falls in."""
    for start_us, end_us, running in reversed(spans):
        if start_us < stamp_us <= end_us:
            return neighbour in running
        if end_us < stamp_us:
            return False
    return False
