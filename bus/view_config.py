"""What a run shows and records (part of bus.config's swarm configuration): run.mcap and the live
Foxglove or Lichtblick view the ground station serves (groundstation.recording)."""

from __future__ import annotations

from pydantic import Field

from bus.strict_model import Strict


class ViewConfig(Strict):
    """What the ground station shows and records for Foxglove or Lichtblick (groundstation.recording)."""

    record: bool = Field(True, description="write run.mcap in the run directory (scene, poses, metrics, events)")
    live: bool = Field(False, description="serve a Foxglove WebSocket live view while the swarm runs")
    live_host: str = Field("127.0.0.1", min_length=1, max_length=255, description="the live view's address")
    live_port: int = Field(8765, ge=1, le=65535, description="the live view's port")
    live_backlog: int = Field(
        1024, ge=1, le=1_000_000, description="messages queued per live viewer; a slow viewer loses the oldest"
    )
    live_speed: float | None = Field(
        None,
        gt=0,
        le=10_000,
        description="lockstep with the live view on: run at most this many times real time, so that a viewer "
        "can watch (the ground station holds its tick acknowledgements; None: as fast as the swarm goes)",
    )
