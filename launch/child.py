"""A process of a swarm as `swarm up` keeps it (its handle, its log, whether the run needs it), and
the router's port: a free one picked, then waited for until the router listens."""

from __future__ import annotations

import socket
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

from bus.errors import SwarmlocError
from launch import children


class ChildFailed(SwarmlocError):
    """A process of the swarm failed to start or died."""


@dataclass
class Child:
    """A child process of the swarm: ``essential`` ones end the run when they die."""

    name: str
    process: children.Forked | subprocess.Popen
    log_path: Path
    essential: bool

    def tail(self, lines: int = 8) -> str:
        """The last ``lines`` of its log, for the message that says it died."""
        try:
            text = self.log_path.read_text(errors="replace").splitlines()
        except OSError:
            return "(no log)"
        return "\n".join(text[-lines:]) or "(empty log)"


def free_port() -> int:
    """A TCP port on the loopback nobody listens on now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_for_port(port: int, timeout_s: float, router: Child) -> None:
    """Until ``router`` listens on ``port``; ChildFailed if it exits or ``timeout_s`` passes first."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if router.process.poll() is not None:
            raise ChildFailed(f"router exited with {router.process.returncode}:\n{router.tail()}")
        with socket.socket() as sock:
            if sock.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.01)
    raise ChildFailed(f"router did not listen on port {port} within {timeout_s:g} s")
