"""The live view's address, checked before any process starts (the ground station serves it)."""

from __future__ import annotations

import socket

from bus.errors import ConfigError


def check_live_address(host: str, port: int) -> None:
    """ConfigError (one line) when nothing could serve on ``host``:``port``: an address that does not
    resolve, is not this machine's, or a port already taken."""
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except (OSError, UnicodeError) as exc:
        raise ConfigError(f"live view: {host!r} is not an address this machine can serve on ({exc})") from None
    family, kind, proto, _, address = infos[0]
    with socket.socket(family, kind, proto) as probe:
        try:
            probe.bind(address)
        except OSError as exc:
            raise ConfigError(f"live view: cannot serve on {host}:{port}: {exc.strerror or exc}") from None
