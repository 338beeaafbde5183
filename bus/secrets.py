"""Secrets of a swarm: the MAVLink 2 signing key and the zenoh user passwords, one per role.

Processes read them from the environment, never from config.json:
``SWARMLOC_MAVLINK_KEY`` (64 hex characters) or ``SWARMLOC_MAVLINK_KEY_FILE``; ``SWARMLOC_ZENOH_USER``
with ``SWARMLOC_ZENOH_PASSWORD`` or ``SWARMLOC_ZENOH_PASSWORD_FILE``. ``write_secrets`` makes a fresh
set in a directory (files readable by the owner only): ``mavlink.key``, ``<role>.password`` and
``credentials.txt``, the router's user:password dictionary.
"""

from __future__ import annotations

import os
import secrets
from pathlib import Path

from bus.errors import ConfigError
from bus.mavlink_codec import load_signing_key

USERS = ("router", "world", "vehicle", "groundstation", "supervisor", "cli")


def _read(path: str, what: str) -> str:
    try:
        return Path(path).read_text().strip()
    except OSError as exc:
        raise ConfigError(f"cannot read {what} {path}: {exc.strerror or exc}") from None


def signing_key_from_env(env: dict[str, str] | None = None) -> bytes | None:
    """The MAVLink signing key (32 bytes) named by the environment, or None (signing off)."""
    env = os.environ if env is None else env
    raw = env.get("SWARMLOC_MAVLINK_KEY") or (
        _read(env["SWARMLOC_MAVLINK_KEY_FILE"], "MAVLink key file") if env.get("SWARMLOC_MAVLINK_KEY_FILE") else None)
    if raw is None:
        return None
    try:
        return load_signing_key(raw)
    except ValueError as exc:
        raise ConfigError(f"MAVLink signing key: {exc} (give 64 hex characters)") from None


def zenoh_login_from_env(env: dict[str, str] | None = None) -> tuple[str, str] | None:
    """(user, password) for zenoh authentication, or None."""
    env = os.environ if env is None else env
    user = env.get("SWARMLOC_ZENOH_USER")
    if not user:
        return None
    password = env.get("SWARMLOC_ZENOH_PASSWORD") or (
        _read(env["SWARMLOC_ZENOH_PASSWORD_FILE"], "zenoh password file") if env.get("SWARMLOC_ZENOH_PASSWORD_FILE") else None)
    if not password:
        raise ConfigError(f"SWARMLOC_ZENOH_USER={user} needs SWARMLOC_ZENOH_PASSWORD or SWARMLOC_ZENOH_PASSWORD_FILE")
    return user, password


def write_secrets(directory: Path) -> Path:
    """A fresh signing key and one password per role in ``directory`` (created, mode 0700)."""
    directory.mkdir(parents=True, exist_ok=True)
    directory.chmod(0o700)
    passwords = {user: secrets.token_urlsafe(24) for user in USERS}
    files = {"mavlink.key": secrets.token_bytes(32).hex(),
             "credentials.txt": "".join(f"{u}:{p}\n" for u, p in passwords.items()),
             **{f"{u}.password": p for u, p in passwords.items()}}
    for name, text in files.items():
        path = directory / name
        path.touch(mode=0o600, exist_ok=True)
        path.write_text(text + ("" if text.endswith("\n") else "\n"))
    return directory


def role_env(directory: Path, user: str) -> dict[str, str]:
    """Environment for a process of role ``user`` using the secrets in ``directory``."""
    return {"SWARMLOC_MAVLINK_KEY_FILE": str(directory / "mavlink.key"), "SWARMLOC_ZENOH_USER": user,
            "SWARMLOC_ZENOH_PASSWORD_FILE": str(directory / f"{user}.password")}
