"""Who joined and who left, as the world's lockstep ticks say (pure).

A vehicle joins when a tick first lists it among the members the world waits for, and leaves when a
tick no longer does. The world decides membership at fixed ticks, so what this yields is
reproducible; when a process hears a liveliness token is not (it races with the next tick's truth).
"""

from __future__ import annotations


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
