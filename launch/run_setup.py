"""What `swarm up` sets up before it starts a swarm's processes: how the run is protected (``Security``),
its run directory, and the terrain model the ground station shows under a camera swarm."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from bus.config import SwarmConfig
from bus.secrets import role_env


@dataclass(frozen=True)
class Security:
    """How `swarm up` protects a run: fresh secrets in ``secrets_dir`` (zenoh logins with access
    control, MAVLink signing), optional TLS files (PEM paths) for the router and its clients, and a
    MAVLink forward to ground-control software."""

    secrets_dir: Path | None = None
    tls_certificate: Path | None = None
    tls_private_key: Path | None = None
    tls_root_ca: Path | None = None
    mavlink_out: str | None = None

    def env(self, user: str) -> dict[str, str]:
        """The environment of a process logging in as ``user`` (a role, or ``vehicle-<id>``)."""
        out = role_env(self.secrets_dir, user) if self.secrets_dir else {}
        if self.tls_root_ca:
            out["SWARMLOC_ZENOH_TLS_ROOT_CA"] = str(self.tls_root_ca)
        return out

    def router_args(self) -> list[str]:
        args = ["--credentials", str(self.secrets_dir / "credentials.txt")] if self.secrets_dir else []
        if self.tls_certificate:
            args += ["--tls-cert", str(self.tls_certificate), "--tls-key", str(self.tls_private_key)]
        return args


def write_terrain_model(config: SwarmConfig, run_dir: Path) -> None:
    """The terrain the cameras see, as the model the ground station shows under the swarm
    (groundstation.recording's /terrain)."""
    from groundstation.recording_start import TERRAIN_MODEL
    from groundstation.terrain_model import terrain_glb
    from sim.terrain import make_terrain

    terrain = make_terrain(config)
    width_m, height_m = terrain.size_m
    (run_dir / TERRAIN_MODEL).write_bytes(terrain_glb(terrain.image, width_m, height_m))


def unique_run_dir(out: Path, name: str) -> Path:
    candidate, n = out / name, 1
    while candidate.exists():
        n += 1
        candidate = out / f"{name}-{n}"
    candidate.mkdir(parents=True)
    return candidate
