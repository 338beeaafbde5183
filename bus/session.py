"""Bus endpoints: a zenoh session and an in-memory twin with the same small API.

Callbacks only enqueue: every subscription delivers into an inbox (a bounded lane of a
``bus.mailbox.Mailbox``, or any object with ``put``) that the process's loop thread drains. A payload
over the subscription's size cap is never copied: an ``Oversized`` marker goes in its place. Roles
are enforced here: a vehicle may not subscribe to truth. A client whose router is not up yet waits
for it, says so once, and gives up with a one-line error when ``connect_timeout_s`` is over.
"""

from __future__ import annotations

import json
import logging
import os
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from bus.config import BusConfig
from bus.errors import AccessDenied, BusUnavailable
from bus.keys import KeySpace
from bus.mailbox import Oversized

log = logging.getLogger("swarmloc.bus")
MAX_QUERY_BYTES = 64 << 10


class Inbox(Protocol):
    def put(self, item: Any) -> Any: ...


@dataclass(frozen=True)
class Envelope:
    key: str
    payload: bytes


@dataclass(frozen=True)
class Request:
    """A query to a queryable: the loop thread answers it once with ``respond(payload)``."""

    key: str
    payload: bytes
    respond: Callable[[bytes], None]


@dataclass(frozen=True)
class LivelinessEvent:
    key: str
    alive: bool


class Publisher(Protocol):
    def put(self, payload: bytes) -> None: ...


def await_subscribers(publishers: dict[str, Any], *, timeout_s: float, stop: Any = None) -> list[str]:
    """Wait until every publisher knows of a matching subscriber; returns the names of those that
    still do not after ``timeout_s``. A zenoh client drops publications for which it knows no
    subscriber yet, and subscriptions propagate asynchronously: a process that publishes before this
    loses its first messages, however it was started."""
    deadline = time.monotonic() + timeout_s
    waiting = dict(publishers)
    while waiting:
        waiting = {name: pub for name, pub in waiting.items() if not pub.matching_status.matching}
        if not waiting or time.monotonic() > deadline or (stop is not None and stop.is_set()):
            break
        time.sleep(0.005)
    return sorted(waiting)


class Bus(Protocol):
    keys: KeySpace
    role: str

    def publisher(self, key: str) -> Publisher: ...
    def subscribe(self, key_expr: str, inbox: Inbox, max_bytes: int | None = None) -> None: ...
    def declare_token(self, key: str) -> None: ...
    def watch_liveliness(self, key_expr: str, inbox: Inbox) -> None: ...
    def queryable(self, key: str, inbox: Inbox) -> None: ...
    def get(self, key: str, payload: bytes, timeout_s: float) -> list[bytes]: ...
    def close(self) -> None: ...


def check_subscription(role: str, keys: KeySpace, key_expr: str) -> None:
    """Raise AccessDenied when ``role`` may not read ``key_expr`` (vehicles never see truth)."""
    if role == "vehicle" and keys.is_truth(key_expr):
        raise AccessDenied(f"role 'vehicle' may not subscribe to truth ({key_expr!r})")


@dataclass(frozen=True)
class Transport:
    """How a process authenticates and encrypts: zenoh user/password, TLS files (PEM paths).

    Clients need ``tls_root_ca`` to reach a ``tls/...`` endpoint; routers listening on TLS need
    ``tls_certificate`` and ``tls_private_key``; a router enforcing logins needs ``credentials_file``
    (``user:password`` lines) and usually ``acl`` (see bus.access)."""

    user: str | None = None
    password: str | None = None
    tls_root_ca: str | None = None
    tls_certificate: str | None = None
    tls_private_key: str | None = None
    credentials_file: str | None = None
    acl: dict | None = None

    @classmethod
    def from_env(cls, env: dict[str, str] | None = None) -> Transport:
        """User, password and TLS root CA from ``SWARMLOC_ZENOH_*`` (see bus.secrets)."""
        from bus.secrets import zenoh_login_from_env

        env = os.environ if env is None else env
        login = zenoh_login_from_env(env)
        return cls(*(login or (None, None)), tls_root_ca=env.get("SWARMLOC_ZENOH_TLS_ROOT_CA") or None)


def zenoh_config(conf: BusConfig, transport: Transport = Transport()):
    """A zenoh.Config from our BusConfig: explicit endpoints, multicast scouting off, shared memory
    off (our messages are a few KB; zenoh would put those over 3 KB in 16 MB pools mapped into every
    process, +45 MB RSS per vehicle and slower), and the transport's login, TLS files, credentials
    dictionary and access control. A router opens at once: zenoh would first spend its scouting delay
    (0.5 s) looking for peers, which multicast being off leaves nothing to find (the endpoints it
    connects to are dialled either way), and a run shorter than that waited for it to end."""
    import zenoh

    zconf = zenoh.Config()
    settings: dict[str, object] = {
        "mode": conf.mode,
        "connect/endpoints": list(conf.connect),
        "listen/endpoints": list(conf.listen),
        "scouting/multicast/enabled": False,
        "transport/shared_memory/enabled": False,
        **({"scouting/delay": 0} if conf.mode == "router" else {}),
    }
    if transport.user:
        settings["transport/auth/usrpwd"] = {
            "user": transport.user,
            "password": transport.password,
            **({"dictionary_file": transport.credentials_file} if transport.credentials_file else {}),
        }
    for key, value in (
        ("root_ca_certificate", transport.tls_root_ca),
        ("listen_certificate", transport.tls_certificate),
        ("listen_private_key", transport.tls_private_key),
    ):
        if value:
            settings[f"transport/link/tls/{key}"] = value
    if transport.acl is not None:
        settings["access_control"] = transport.acl
    for key, value in settings.items():
        zconf.insert_json5(key, json.dumps(value))
    return zconf


def _reachable(endpoint: str, timeout_s: float = 0.5) -> bool:
    """True when something accepts TCP connections at a ``tcp/`` or ``tls/`` endpoint."""
    scheme, _, address = endpoint.partition("/")
    host, _, port = address.split("#")[0].rpartition(":")
    if scheme not in ("tcp", "tls") or not port.isdigit():
        return False
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s):
            return True
    except OSError:
        return False


def open_session(conf: BusConfig, transport: Transport, zenoh_module: Any) -> Any:
    """Open a zenoh session; a client waits (with backoff) for a router that is not up yet.

    A router that accepts TCP connections but refuses the session has refused the login or the TLS
    handshake: that fails at once (after one retry, for a router that is still starting)."""
    who = f"{', '.join(conf.connect) or 'no endpoint'} as {transport.user or 'anonymous'}"
    deadline = time.monotonic() + conf.connect_timeout_s
    delay, refusals, announced = 0.2, 0, False
    while True:
        try:
            return zenoh_module.open(zenoh_config(conf, transport))
        except zenoh_module.ZError as exc:
            detail = str(exc).split(" at ")[0]
            if conf.mode != "client" or not conf.connect:
                raise BusUnavailable(f"cannot open a zenoh {conf.mode} at {who}: {detail}") from None
            if any(_reachable(e) for e in conf.connect):
                refusals += 1
                if refusals >= 2:
                    raise BusUnavailable(
                        f"cannot join the swarm at {who}: the router refused the login or the TLS handshake ({detail})"
                    ) from None
            if time.monotonic() + delay > deadline:
                raise BusUnavailable(
                    f"cannot join the swarm at {who}: no zenoh router answered within {conf.connect_timeout_s:g} s"
                ) from None
            if not announced:
                log.warning(
                    "waiting for the zenoh router at %s (up to %g s)", ", ".join(conf.connect), conf.connect_timeout_s
                )
                announced = True
            time.sleep(delay)
            delay = min(2.0, delay * 1.5)


class ZenohBus:
    """A zenoh session with swarmloc's role checks; use as a context manager so it always closes."""

    def __init__(self, conf: BusConfig, *, role: str, transport: Transport = Transport()) -> None:
        import zenoh

        self._zenoh = zenoh
        self.keys = KeySpace(conf.prefix)
        self.role = role
        self._session = open_session(conf, transport, zenoh)
        self._keep: list[object] = []

    def publisher(self, key: str) -> Publisher:
        pub = self._session.declare_publisher(key, congestion_control=self._zenoh.CongestionControl.BLOCK)
        self._keep.append(pub)
        return pub

    def subscribe(self, key_expr: str, inbox: Inbox, max_bytes: int | None = None) -> None:
        """Samples on ``key_expr`` go to ``inbox`` as Envelopes; those over ``max_bytes`` as Oversized."""
        check_subscription(self.role, self.keys, key_expr)
        cap = max_bytes if max_bytes is not None else 1 << 62

        def on_sample(sample) -> None:
            size = len(sample.payload)
            if size > cap:
                inbox.put(Oversized(str(sample.key_expr), size))
            else:
                inbox.put(Envelope(str(sample.key_expr), sample.payload.to_bytes()))

        self._keep.append(self._session.declare_subscriber(key_expr, on_sample))

    def declare_token(self, key: str) -> None:
        self._keep.append(self._session.liveliness().declare_token(key))

    def watch_liveliness(self, key_expr: str, inbox: Inbox) -> None:
        put_kind = self._zenoh.SampleKind.PUT

        def on_change(sample) -> None:
            inbox.put(LivelinessEvent(str(sample.key_expr), sample.kind == put_kind))

        self._keep.append(self._session.liveliness().declare_subscriber(key_expr, on_change, history=True))

    def queryable(self, key: str, inbox: Inbox) -> None:
        """Queries on ``key`` arrive in ``inbox`` as Request items (answered later by the loop thread)."""

        def on_query(query) -> None:
            def respond(payload: bytes) -> None:
                query.reply(query.key_expr, payload)
                query.drop()

            payload = query.payload
            if payload is not None and len(payload) > MAX_QUERY_BYTES:
                query.drop()
                inbox.put(Oversized(str(query.key_expr), len(payload)))
                return
            inbox.put(Request(str(query.key_expr), payload.to_bytes() if payload else b"", respond))

        self._keep.append(self._session.declare_queryable(key, on_query))

    def get(self, key: str, payload: bytes, timeout_s: float) -> list[bytes]:
        """Ask the queryables on ``key``; their replies (empty when nobody answers within the timeout)."""
        return [
            r.ok.payload.to_bytes()
            for r in self._session.get(key, payload=payload, timeout=timeout_s)
            if r.ok and len(r.ok.payload) <= MAX_QUERY_BYTES
        ]

    def close(self) -> None:
        if not self._session.is_closed():
            self._keep.clear()
            self._session.close()

    def __enter__(self) -> ZenohBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
