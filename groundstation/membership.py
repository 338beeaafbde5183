"""Who is on the bus (pure): the world, the vehicles alive, those gone; and who joined and who left as
the world's lockstep ticks say.

A vehicle joins when a tick first lists it among the members the world waits for, and leaves when a
tick no longer does. The world decides membership at fixed ticks, so what this yields is
reproducible; when a process hears a liveliness token is not (it races with the next tick's truth).
"""

from __future__ import annotations

from collections.abc import Callable


class MembershipLog:
    """The members of the last tick seen; ``change`` says who came and went since."""

    def __init__(self, *, resumed: bool) -> None:
        self._resumed = resumed  # a restarted ground station: the first tick's members joined long ago
        self._members: set[int] | None = None

    def change(self, members: tuple[int, ...]) -> tuple[list[int], list[int]]:
        """(joined, left) vehicle ids, each sorted, between the previous tick's members and these."""
        now = set(members)
        before = self._members if self._members is not None else (now if self._resumed else set())
        self._members = now
        return sorted(now - before), sorted(before - now)


class Presence:
    """Who is on the bus, as the liveliness tokens say (``token``) and, in lockstep, the world's ticks
    (``tick``): the world (alive now, seen at all), the vehicles alive (``active``) and gone
    (``departed``), and after which stamp a vehicle that rejoined publishes (``rejoined_us``)."""

    def __init__(self, *, resumed: bool) -> None:
        self.active: set[int] = set()
        self.departed: set[int] = set()
        self.rejoined_us: dict[int, int] = {}
        self.world_alive = self.world_seen = False
        self._members = MembershipLog(resumed=resumed)

    def token(
        self, role: str, vid: int | None, alive: bool, before_first_tick: bool, completed: Callable[[int], bool]
    ) -> str | None:
        """A liveliness token of ``role`` (and vehicle ``vid``) appeared or went; the event it means
        (vehicle_joined, vehicle_left, vehicle_lost: ``completed(vid)`` tells the last two apart), None
        for none. ``before_first_tick``: a restarted ground station meets vehicles that joined long ago."""
        if role == "world":
            self.world_alive, self.world_seen = alive, self.world_seen or alive
            return None
        if role != "vehicle" or vid is None:
            return None  # the supervisor, routers, itself: nothing to score
        if before_first_tick and alive:
            self.active.add(vid)
            return None
        kind = "vehicle_joined" if alive else ("vehicle_left" if completed(vid) else "vehicle_lost")
        (self.active.add if alive else self.active.discard)(vid)
        (self.departed.discard if alive else self.departed.add)(vid)
        return kind

    def tick(
        self, members: tuple[int, ...], previous_tick_us: int, completed: Callable[[int], bool]
    ) -> list[tuple[str, int]]:
        """Lockstep: the joins and departures (event kind, vehicle) a tick listing ``members`` says; a
        vehicle that joins after the first tick publishes only past ``previous_tick_us``."""
        joined, left = self._members.change(members)
        for vid in joined:
            if previous_tick_us >= 0:  # it cycles from its first tick on, past the previous one's stamp
                self.rejoined_us[vid] = previous_tick_us
        return [("vehicle_joined", vid) for vid in joined] + [
            ("vehicle_left" if completed(vid) else "vehicle_lost", vid) for vid in left
        ]
