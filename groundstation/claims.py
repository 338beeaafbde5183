"""The ground station's register of claimed vehicle ids (pure; persisted in the run directory so a
restarted ground station keeps it)."""

from __future__ import annotations

import json
from pathlib import Path

from bus.claims import ClaimReply, ClaimRequest


class IdRegister:
    def __init__(self, *, vehicles: int, path: Path) -> None:
        self.vehicles, self.path = vehicles, path
        self.ids: dict[str, int] = {}
        self.claims: dict[str, int] = {}
        if path.exists():
            try:
                saved = json.loads(path.read_text())
                self.ids, self.claims = dict(saved["ids"]), dict(saved["claims"])
            except (json.JSONDecodeError, KeyError, TypeError, ValueError):
                pass

    def claim(self, request: ClaimRequest) -> ClaimReply:
        """The host's id (its old one after a restart, else the lowest free one)."""
        host = request.host
        if host not in self.ids:
            free = sorted(set(range(1, self.vehicles + 1)) - set(self.ids.values()))
            if not free:
                return ClaimReply(ok=False, error=f"the swarm is full: {self.vehicles} vehicles have claimed their ids")
            self.ids[host] = free[0]
        self.claims[host] = self.claims.get(host, 0) + 1
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(json.dumps({"ids": self.ids, "claims": self.claims}, sort_keys=True))
        tmp.replace(self.path)
        return ClaimReply(ok=True, vehicle_id=self.ids[host], restarts=self.claims[host] - 1)
