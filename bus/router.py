"""A zenoh router process, opened from Python (no separate zenohd needed)."""

from __future__ import annotations

import threading

from bus.config import BusConfig
from bus.session import Transport, zenoh_config


def run_router(
    listen: tuple[str, ...], stop: threading.Event, *, connect: tuple[str, ...] = (), transport: Transport = Transport()
) -> None:
    """Route until ``stop``; ``connect`` joins other routers (multi-host), ``transport`` sets logins,
    access control and TLS (see bus.session.Transport)."""
    import zenoh

    conf = BusConfig(mode="router", listen=listen, connect=connect)
    with zenoh.open(zenoh_config(conf, transport)):
        while not stop.wait(0.5):
            pass
