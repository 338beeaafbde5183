"""Test hosts as Linux network namespaces on one machine, joined by veth links to a bridge that
lives in a namespace of its own (the machine's own network is not touched)."""

from __future__ import annotations

import os
import shutil
import subprocess


def _ip(*args: str) -> None:
    subprocess.run(["ip", *args], check=True, capture_output=True, text=True)


def netns_unavailable() -> str | None:
    """Why network namespaces cannot be used here, or None when they can."""
    if shutil.which("ip") is None:
        return "iproute2 (`ip`) is not installed"
    probe = f"swlprobe{os.getpid()}"
    try:
        _ip("netns", "add", probe)
    except subprocess.CalledProcessError as exc:
        return f"cannot create network namespaces ({exc.stderr.strip() or 'needs root or CAP_SYS_ADMIN'})"
    _ip("netns", "del", probe)
    return None


class Lab:
    """Hosts ``name -> 10.213.<n>.x/24`` on one switch; ``run`` starts a command on a host."""

    def __init__(self, hosts: list[str]) -> None:
        self.tag = f"{os.getpid() % 100000}"
        self.switch = f"swlsw{self.tag}"
        self.addresses: dict[str, str] = {}
        self.namespaces: list[str] = [self.switch]
        _ip("netns", "add", self.switch)
        self._in(self.switch, "link", "add", "br0", "type", "bridge")
        self._in(self.switch, "link", "set", "br0", "up")
        for n, host in enumerate(hosts, start=1):
            self._add_host(host, n)

    def ns(self, host: str) -> str:
        return f"swl{host}{self.tag}"

    def _in(self, ns: str, *args: str) -> None:
        _ip("netns", "exec", ns, "ip", *args)

    def _add_host(self, host: str, n: int) -> None:
        ns, here, there = self.ns(host), f"h{n}x{self.tag}", f"s{n}x{self.tag}"
        _ip("netns", "add", ns)
        self.namespaces.append(ns)
        _ip("link", "add", here, "type", "veth", "peer", "name", there)
        _ip("link", "set", here, "netns", ns)
        _ip("link", "set", there, "netns", self.switch)
        self._in(self.switch, "link", "set", there, "master", "br0")
        self._in(self.switch, "link", "set", there, "up")
        self.addresses[host] = f"10.213.0.{n}"
        self._in(ns, "addr", "add", f"{self.addresses[host]}/24", "dev", here)
        self._in(ns, "link", "set", here, "up")
        self._in(ns, "link", "set", "lo", "up")

    def run(self, host: str, argv: list[str], *, env: dict[str, str], log) -> subprocess.Popen:
        return subprocess.Popen(
            ["ip", "netns", "exec", self.ns(host), *argv], env=env, stdout=log, stderr=log, stdin=subprocess.DEVNULL
        )

    def close(self) -> None:
        for ns in reversed(self.namespaces):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
