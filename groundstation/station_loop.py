"""The ground station's loop: handle inbox items until the world ends the run (or a stop signal),
let stragglers land, then write the summary."""

from __future__ import annotations

import queue
import threading
import time
from pathlib import Path

from bus.config import SwarmConfig
from bus.session import Bus
from groundstation.mavlink_out import MavlinkForwarder
from groundstation.node import GroundStation

END_GRACE_S = 0.3


def run_groundstation(bus: Bus, config: SwarmConfig, run_dir: Path, stop: threading.Event,
                      on_progress=None, *, signing_key: bytes | None = None,
                      forwarder: MavlinkForwarder | None = None) -> dict:
    """Score until the world ends the run (or ``stop`` is set); returns the summary."""
    gs = GroundStation(bus, config, run_dir, signing_key=signing_key, forwarder=forwarder)
    if on_progress is not None:
        gs.on_progress = on_progress
    gs.publish_plan()
    while not gs.ended and not stop.is_set():
        try:
            gs.handle(gs.inbox.get(timeout=0.2))
        except queue.Empty:
            gs.run.maybe_flush()
    _drain(gs, END_GRACE_S)  # keys are not ordered among each other: let stragglers land
    return gs.finish("complete" if gs.ended else "interrupted")


def _drain(gs: GroundStation, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        try:
            gs.handle(gs.inbox.get(timeout=max(0.0, deadline - time.monotonic())))
        except queue.Empty:
            return
