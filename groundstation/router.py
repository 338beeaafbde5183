"""A zenoh router process, opened from Python (no separate zenohd needed)."""

from __future__ import annotations

import threading

from bus.config import BusConfig
from bus.session import zenoh_config


def run_router(listen: tuple[str, ...], stop: threading.Event) -> None:
    import zenoh

    conf = BusConfig(mode="router", listen=listen, connect=())
    with zenoh.open(zenoh_config(conf)):
        while not stop.wait(0.5):
            pass
