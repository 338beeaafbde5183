"""Secrets of a swarm: a master MAVLink signing key, one zenoh login per role, and one login and one
signing key per vehicle.

Who holds what (the trust model, see README "Security"):

- the ground station holds the master key (``mavlink.key``): it derives every vehicle's signing key
  and password from it, to verify each vehicle's MAVLink stream and to hand a vehicle its secrets
  when it claims an id (``--id auto``);
- vehicle ``i`` holds only its own login ``vehicle-i`` and its own key ``vehicle-i.key``; the router
  lets that login publish only under ``v/i/`` and ``ctl/ack/i`` (bus.access);
- ``enroll`` is the login of vehicles that do not know their id yet (compose replicas): it may only
  ask the ground station for an id;
- the world, the supervisor and the CLI hold their own logins and no signing key.

Processes read secrets from the environment, never from config files: ``SWARMLOC_MAVLINK_KEY`` (64
hex characters) or ``SWARMLOC_MAVLINK_KEY_FILE``; ``SWARMLOC_ZENOH_USER`` with
``SWARMLOC_ZENOH_PASSWORD`` or ``SWARMLOC_ZENOH_PASSWORD_FILE``.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import os
import re
import secrets
from pathlib import Path

from bus.errors import ConfigError
from bus.mavlink_codec import load_signing_key

ROLE_USERS = ("router", "world", "groundstation", "supervisor", "cli", "enroll")
VEHICLE_USER = re.compile(r"vehicle-([1-9][0-9]{0,2})")


def vehicle_user(vehicle_id: int) -> str:
    return f"vehicle-{vehicle_id}"


def vehicle_signing_key(master: bytes, vehicle_id: int) -> bytes:
    """Vehicle ``vehicle_id``'s 32-byte MAVLink signing key, derived from the master key (HMAC-SHA256)."""
    return hmac.new(master, f"swarmloc/mavlink-signing/vehicle/{vehicle_id}".encode(), hashlib.sha256).digest()


def vehicle_password(master: bytes, vehicle_id: int) -> str:
    """Vehicle ``vehicle_id``'s zenoh password, derived from the master key."""
    digest = hmac.new(master, f"swarmloc/zenoh-password/vehicle/{vehicle_id}".encode(), hashlib.sha256).digest()
    return base64.urlsafe_b64encode(digest[:24]).decode()


def _read(path: str, what: str) -> str:
    try:
        return Path(path).read_text().strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read {what} {path}: {getattr(exc, 'strerror', None) or exc}") from None


def signing_key_from_env(env: dict[str, str] | None = None) -> bytes | None:
    """The MAVLink signing key (32 bytes) named by the environment, or None (signing off)."""
    env = os.environ if env is None else env
    raw = env.get("SWARMLOC_MAVLINK_KEY") or (
        _read(env["SWARMLOC_MAVLINK_KEY_FILE"], "MAVLink key file") if env.get("SWARMLOC_MAVLINK_KEY_FILE") else None
    )
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
        _read(env["SWARMLOC_ZENOH_PASSWORD_FILE"], "zenoh password file")
        if env.get("SWARMLOC_ZENOH_PASSWORD_FILE")
        else None
    )
    if not password:
        raise ConfigError(f"SWARMLOC_ZENOH_USER={user} needs SWARMLOC_ZENOH_PASSWORD or SWARMLOC_ZENOH_PASSWORD_FILE")
    return user, password


def _write(path: Path, text: str) -> None:
    path.touch(mode=0o600, exist_ok=True)
    path.chmod(0o600)
    path.write_text(text if text.endswith("\n") else text + "\n")


def write_secrets(directory: Path, *, vehicles: int) -> Path:
    """A fresh master key, one password per role, and per-vehicle logins and keys for vehicles
    1..``vehicles`` in ``directory`` (created, mode 0700, files 0600); ``credentials.txt`` is the
    router's user:password dictionary."""
    if not 1 <= vehicles <= 250:
        raise ConfigError(f"secrets for 1-250 vehicles, not {vehicles}")
    directory.mkdir(parents=True, exist_ok=True)
    directory.chmod(0o700)
    master = secrets.token_bytes(32)
    passwords = {user: secrets.token_urlsafe(24) for user in ROLE_USERS}
    passwords.update({vehicle_user(i): vehicle_password(master, i) for i in range(1, vehicles + 1)})
    _write(directory / "mavlink.key", master.hex())
    _write(directory / "credentials.txt", "".join(f"{u}:{p}\n" for u, p in passwords.items()))
    for user, password in passwords.items():
        _write(directory / f"{user}.password", password)
    for i in range(1, vehicles + 1):
        _write(directory / f"{vehicle_user(i)}.key", vehicle_signing_key(master, i).hex())
    return directory


def role_env(directory: Path, user: str) -> dict[str, str]:
    """Environment for a process logging in as ``user`` with the secrets in ``directory``: only the
    ground station gets the master key, a vehicle only its own key."""
    env = {"SWARMLOC_ZENOH_USER": user, "SWARMLOC_ZENOH_PASSWORD_FILE": str(directory / f"{user}.password")}
    if user == "groundstation":
        env["SWARMLOC_MAVLINK_KEY_FILE"] = str(directory / "mavlink.key")
    elif VEHICLE_USER.fullmatch(user):
        env["SWARMLOC_MAVLINK_KEY_FILE"] = str(directory / f"{user}.key")
    return env


def credential_users(credentials_file: Path) -> list[str]:
    """The user names of a router's credentials file (``user:password`` lines)."""
    try:
        lines = credentials_file.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read credentials file {credentials_file}: {exc}") from None
    return [line.split(":", 1)[0] for line in lines if ":" in line]
