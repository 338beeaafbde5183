"""Forwards every vehicle's genuine MAVLink frames to ground-control software over UDP
(QGroundControl and MAVProxy listen on udp port 14550). Each vehicle's stream carries its own
HEARTBEAT (sysid = vehicle id), so a GCS sees one vehicle per sysid."""

from __future__ import annotations

import re
import socket

from bus.errors import ConfigError

DEFAULT_PORT = 14550


def parse_udpout(url: str) -> tuple[str, int]:
    """'udpout:HOST[:PORT]' (pymavlink's notation) -> (host, port)."""
    match = re.fullmatch(r"udpout:([^:]+)(?::(\d{1,5}))?", url.strip())
    if not match or not 0 < int(match.group(2) or DEFAULT_PORT) < 65536:
        raise ConfigError(f"--mavlink-out: expected udpout:HOST[:PORT], got {url!r}")
    return match.group(1), int(match.group(2) or DEFAULT_PORT)


class MavlinkForwarder:
    def __init__(self, url: str) -> None:
        self.address = parse_udpout(url)
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sent = 0
        self.failed = 0

    def forward(self, frame: bytes) -> None:
        try:
            self._socket.sendto(frame, self.address)
            self.sent += 1
        except OSError:  # nobody listening, unreachable host: a GCS link never stops the ground station
            self.failed += 1

    def close(self) -> None:
        self._socket.close()
