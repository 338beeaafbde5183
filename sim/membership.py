"""The world's record of the swarm's members: which vehicles are alive, joining or dead, which have
acknowledged the current tick, whether the ground station and the supervisor are there, and how many
V2V broadcasts each vehicle has sent (summed over its restarts) for lockstep's V2V barrier."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

log = logging.getLogger("swarmloc.world")


@dataclass
class Membership:
    """Which vehicles are alive and which have acknowledged the current tick; how many V2V
    broadcasts each has sent (summed over its restarts)."""

    expected: set[int]
    alive: set[int] = field(default_factory=set)
    joining: set[int] = field(default_factory=set)  # restarted: in lockstep once their first ack (any tick) arrives
    groundstation: bool = False
    supervisor: bool = False  # `swarm up` executes kill faults; lockstep holds the clock for them
    gs_seen: bool = False
    gs_acked: int = -1
    gs_returned: bool = False  # a restarted ground station is back: it acks only ticks it sees
    acked: set[int] = field(default_factory=set)
    dead: set[int] = field(default_factory=set)
    v2v_base: dict[int, int] = field(default_factory=dict)
    v2v_last: dict[int, int] = field(default_factory=dict)
    started: bool = False  # the first tick went out

    def on_token(self, role: str, vid: int | None, alive: bool) -> None:
        if role == "groundstation":
            self.gs_returned = self.gs_returned or (alive and self.gs_seen and not self.groundstation)
            self.groundstation = alive
            self.gs_seen = self.gs_seen or alive
        elif role == "supervisor":
            self.supervisor = alive
        elif role == "vehicle" and vid in self.expected:
            if alive and vid in self.dead and not self.started:
                # its token went and came back before the run began (a session that missed its lease
                # on a starved machine: 3 of 250 vehicles starting on two cores): nothing missed
                log.info("vehicle %d is back before the first tick; it is in the lockstep set again", vid)
                self.dead.discard(vid)
                self.alive.add(vid)
            elif alive and vid in self.dead:
                log.info("vehicle %d is back; it joins the lockstep set with its first ack", vid)
                self.dead.discard(vid)
                self.joining.add(vid)
            elif alive:
                self.alive.add(vid)
            elif vid in self.alive or vid in self.joining:
                self.joining.discard(vid)
                self.declare_dead(vid, "liveliness lost")

    def on_v2v_count(self, vid: int, sent: int) -> None:
        """A restarted vehicle counts from zero again: what it sent before is added to its base."""
        last = self.v2v_last.get(vid, 0)
        if sent < last:
            self.v2v_base[vid] = self.v2v_base.get(vid, 0) + last
        self.v2v_last[vid] = sent

    def v2v_published(self, vehicles: int) -> tuple[int, ...]:
        return tuple(self.v2v_base.get(v, 0) + self.v2v_last.get(v, 0) for v in range(1, vehicles + 1))

    def declare_dead(self, vid: int, reason: str) -> None:
        log.warning("vehicle %d leaves the lockstep set: %s", vid, reason)
        self.alive.discard(vid)
        self.dead.add(vid)

    def everyone_joined(self) -> bool:
        return self.groundstation and self.expected <= self.alive
