"""Is the world there? A vehicle watches the world's liveliness token (and the ground station's and its
neighbours'): a world gone for longer than ``world_timeout_s`` ends the vehicle's run."""

from __future__ import annotations

import time

from bus.errors import SwarmlocError


class WorldGone(SwarmlocError):
    """The world left (or never came back) for longer than the vehicle's ``world_timeout_s``."""


class WorldWatch:
    """Is the world there? Its liveliness token says; gone for ``timeout_s`` means the run is over.
    Also notes a ground station that (re)appears (``gs_arrived`` until the loop has handled it) and
    neighbours that died (``departed``: nobody waits for their broadcasts)."""

    def __init__(self, *, timeout_s: float) -> None:
        self.timeout_s, self.seen, self.gone_since = timeout_s, False, None
        self.gs_arrived = False
        self.departed: set[int] = set()  # neighbours whose liveliness token went away (and has not come back)

    def on_token(self, parsed, alive: bool) -> None:
        if parsed is not None and parsed.role == "vehicle" and parsed.vehicle_id is not None:
            (self.departed.discard if alive else self.departed.add)(parsed.vehicle_id)
            return
        if parsed is not None and parsed.role == "groundstation":
            self.gs_arrived = self.gs_arrived or alive
            return
        if parsed is None or parsed.role != "world":
            return
        self.seen = self.seen or alive
        self.gone_since = None if alive else time.monotonic()

    def check(self) -> None:
        if self.seen and self.gone_since is not None and time.monotonic() - self.gone_since > self.timeout_s:
            raise WorldGone(f"the world has been gone for {self.timeout_s:g} s; the vehicle stops")
