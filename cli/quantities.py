"""Quantities as a person types them on the command line: '200ms', '25m', '30%', '40,10', 'v3'."""

from __future__ import annotations

import re

from bus.errors import ConfigError

_UNITS_S = {"us": 1e-6, "ms": 1e-3, "s": 1.0, "min": 60.0, "": 1.0}
_UNITS_M = {"m": 1.0, "km": 1000.0, "": 1.0}


def _quantity(text: str, units: dict[str, float], what: str) -> float:
    match = re.fullmatch(r"\s*([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)\s*([a-z]*)\s*", text)
    if not match or match.group(2) not in units:
        raise ConfigError(f"{what}: cannot read {text!r} (units: {', '.join(u for u in units if u)})")
    return float(match.group(1)) * units[match.group(2)]


def seconds(text: str | None, what: str) -> float | None:
    """'200ms', '10s', '1.5', '2min' -> seconds (None stays None)."""
    return None if text is None else _quantity(text, _UNITS_S, what)


def metres(text: str | None, what: str) -> float | None:
    return None if text is None else _quantity(text, _UNITS_M, what)


def percent(text: str | None) -> float | None:
    return None if text is None else _quantity(text.rstrip("%"), {"": 1.0}, "--percent")


def centre(text: str | None, flag: str = "--center") -> list[float] | None:
    """'X,Y' in metres (units allowed on each) -> [x, y]."""
    if text is None:
        return None
    parts = text.split(",")
    if len(parts) != 2:
        raise ConfigError(f"{flag}: expected X,Y in metres, got {text!r}")
    return [metres(p, flag) for p in parts]


def vehicle_number(text: str) -> int:
    match = re.fullmatch(r"v?(\d+)", text.strip())
    if not match:
        raise ConfigError(f"not a vehicle: {text!r} (use v<id> or <id>)")
    return int(match.group(1))


def vehicle_numbers(text: str, flag: str) -> list[int]:
    """'v1,v2' or '1,2' -> [1, 2]."""
    try:
        return [vehicle_number(part) for part in text.split(",")]
    except ConfigError as exc:
        raise ConfigError(f"{flag}: {exc}") from None
