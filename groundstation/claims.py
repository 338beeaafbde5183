"""The ground station's register of claimed vehicle ids (pure; persisted in the run directory so a
restarted ground station keeps it). With the master key it hands each claimer its vehicle's own
secrets (bus.secrets derives them)."""

from __future__ import annotations

import json
from pathlib import Path

from bus.claims import ClaimReply, ClaimRequest
from bus.secrets import vehicle_password, vehicle_signing_key


class IdRegister:
    def __init__(self, *, vehicles: int, path: Path, master_key: bytes | None = None) -> None:
        self.vehicles, self.path, self.master_key = vehicles, path, master_key
        self.ids: dict[str, int] = {}
        self.claims: dict[str, int] = {}
        if path.exists():
            try:
                saved = json.loads(path.read_text())
                self.ids, self.claims = dict(saved["ids"]), dict(saved["claims"])
            except (json.JSONDecodeError, KeyError, TypeError, ValueError):
                pass

    def claim(self, request: ClaimRequest, alive: set[int] = frozenset()) -> ClaimReply:
        """The host's id (its old one after a restart, else the lowest free one); refused while the
        vehicle of that id is alive (a second process must not take its identity)."""
        host = request.host
        if host in self.ids and self.ids[host] in alive:
            return ClaimReply(ok=False, error=f"vehicle {self.ids[host]} of host {host} is alive; its id is taken")
        if host not in self.ids:
            free = sorted(set(range(1, self.vehicles + 1)) - set(self.ids.values()))
            if not free:
                return ClaimReply(ok=False, error=f"the swarm is full: {self.vehicles} vehicles have claimed their ids")
            self.ids[host] = free[0]
        self.claims[host] = self.claims.get(host, 0) + 1
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(json.dumps({"ids": self.ids, "claims": self.claims}, sort_keys=True))
        tmp.replace(self.path)
        vid = self.ids[host]
        secrets = (
            {}
            if self.master_key is None
            else {
                "zenoh_password": vehicle_password(self.master_key, vid),
                "signing_key": vehicle_signing_key(self.master_key, vid).hex(),
            }
        )
        return ClaimReply(ok=True, vehicle_id=vid, restarts=self.claims[host] - 1, **secrets)
