"""The live view's server side (groundstation.recording): counting the SDK's reports of a viewer's
full queue, and noticing a viewer's subscription to the terrain (the live view keeps nothing, so the
terrain is logged again for it). Both are called on the SDK's threads."""

from __future__ import annotations

import logging
import threading
from typing import Any

SDK_OVERFLOW_LOGGER = "foxglove.websocket.connected_client.send_lossy"  # "outbox for client ... full"


class OverflowCounter(logging.Handler):
    """Counts the SDK's reports of a viewer's full queue (they come on the SDK's threads)."""

    def __init__(self) -> None:
        super().__init__(level=logging.DEBUG)
        self._count, self._count_lock = 0, threading.Lock()

    def emit(self, record: logging.LogRecord) -> None:
        if "full" in record.getMessage():
            with self._count_lock:
                self._count += 1

    def take(self) -> int:
        with self._count_lock:
            count, self._count = self._count, 0
        return count


def terrain_requests(wanted: threading.Event) -> Any:
    """A foxglove ServerListener: a viewer's subscription to /terrain sets ``wanted``."""
    from foxglove.websocket import ServerListener

    class TerrainRequests(ServerListener):
        def on_subscribe(self, client: Any, channel: Any) -> None:
            if channel.topic == "/terrain":
                wanted.set()

    return TerrainRequests()
