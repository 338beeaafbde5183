"""An in-memory bus with the ZenohBus API, for unit tests and fast Monte Carlo runs in one process."""

from __future__ import annotations

import functools
import queue
import threading

from bus.keys import KeySpace
from bus.mailbox import Oversized
from bus.session import Envelope, Inbox, LivelinessEvent, Request, check_subscription


@functools.lru_cache(maxsize=65536)
def _intersects(a: str, b: str) -> bool:
    import zenoh

    return zenoh.KeyExpr(a).intersects(zenoh.KeyExpr(b))


class MemoryHub:
    """The shared medium: every MemoryBus connected to one hub sees the others' puts and tokens."""

    def __init__(self, prefix: str = "swarm") -> None:
        self.prefix = prefix
        self._lock = threading.Lock()
        self._subscriptions: list[tuple[str, Inbox, int]] = []
        self._watchers: list[tuple[str, Inbox]] = []
        self._tokens: dict[str, int] = {}
        self._queryables: list[tuple[str, Inbox]] = []

    def connect(self, role: str) -> MemoryBus:
        return MemoryBus(self, role=role)

    def deliver(self, key: str, payload: bytes) -> None:
        with self._lock:
            targets = [(inbox, cap) for expr, inbox, cap in self._subscriptions if _intersects(expr, key)]
        for inbox, cap in targets:
            inbox.put(Envelope(key, payload) if len(payload) <= cap else Oversized(key, len(payload)))

    def add_subscription(self, key_expr: str, inbox: Inbox, max_bytes: int | None = None) -> None:
        with self._lock:
            self._subscriptions.append((key_expr, inbox, 1 << 62 if max_bytes is None else max_bytes))

    def add_watcher(self, key_expr: str, inbox: Inbox) -> None:
        with self._lock:
            self._watchers.append((key_expr, inbox))
            alive = [key for key in self._tokens if _intersects(key_expr, key)]
        for key in alive:
            inbox.put(LivelinessEvent(key, True))

    def add_queryable(self, key: str, inbox: Inbox) -> None:
        with self._lock:
            self._queryables.append((key, inbox))

    def query(self, key: str, payload: bytes, timeout_s: float) -> list[bytes]:
        with self._lock:
            targets = [inbox for expr, inbox in self._queryables if _intersects(expr, key)]
        replies: queue.SimpleQueue = queue.SimpleQueue()
        for inbox in targets:
            inbox.put(Request(key, payload, replies.put))
        out = []
        for _ in targets:
            try:
                out.append(replies.get(timeout=timeout_s))
            except queue.Empty:
                break
        return out

    def set_token(self, key: str, alive: bool) -> None:
        with self._lock:
            self._tokens[key] = self._tokens.get(key, 0) + (1 if alive else -1)
            if self._tokens[key] <= 0:
                del self._tokens[key]
            targets = [inbox for expr, inbox in self._watchers if _intersects(expr, key)]
        for inbox in targets:
            inbox.put(LivelinessEvent(key, alive))


class _Matching:
    matching = True


class _MemoryPublisher:
    matching_status = _Matching()  # the in-memory hub delivers synchronously: nothing to wait for

    def __init__(self, hub: MemoryHub, key: str) -> None:
        self._hub, self._key = hub, key

    def put(self, payload: bytes) -> None:
        self._hub.deliver(self._key, bytes(payload))


class MemoryBus:
    def __init__(self, hub: MemoryHub, *, role: str) -> None:
        self._hub = hub
        self.keys = KeySpace(hub.prefix)
        self.role = role
        self._tokens: list[str] = []

    def publisher(self, key: str) -> _MemoryPublisher:
        return _MemoryPublisher(self._hub, key)

    def subscribe(self, key_expr: str, inbox: Inbox, max_bytes: int | None = None) -> None:
        check_subscription(self.role, self.keys, key_expr)
        self._hub.add_subscription(key_expr, inbox, max_bytes)

    def declare_token(self, key: str) -> None:
        self._tokens.append(key)
        self._hub.set_token(key, True)

    def watch_liveliness(self, key_expr: str, inbox: Inbox) -> None:
        self._hub.add_watcher(key_expr, inbox)

    def queryable(self, key: str, inbox: Inbox) -> None:
        self._hub.add_queryable(key, inbox)

    def get(self, key: str, payload: bytes, timeout_s: float) -> list[bytes]:
        return self._hub.query(key, payload, timeout_s)

    def close(self) -> None:
        for key in self._tokens:
            self._hub.set_token(key, False)
        self._tokens.clear()

    def __enter__(self) -> MemoryBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
