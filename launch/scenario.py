"""Scenario files: TOML holding any part of the swarm configuration plus a fault timeline.

    name = "gnss-jamming"
    [world]
    vehicles = 5
    [clock]
    duration_s = 90
    [[faults]]
    kind = "jam-gnss"
    center_m = [0.0, 0.0]
    radius_m = 25.0
    start_s = 20.0
    for_s = 30.0

Command-line options given to `swarm up` override the scenario's values.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from bus.errors import ConfigError


def load_scenario(path: Path) -> dict[str, Any]:
    """The scenario as a nested dict (validated later, with the overrides, by ``build_config``)."""
    try:
        return tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"cannot read scenario {path}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"scenario {path} is not valid TOML: {exc}") from None


def overlay(base: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """``base`` with ``overrides`` merged in, section by section; None values in overrides are skipped."""
    merged = dict(base)
    for key, value in overrides.items():
        if isinstance(value, dict):
            section = merged.get(key)
            merged[key] = overlay(section if isinstance(section, dict) else {}, value)
        elif value is not None:
            merged[key] = value
    return merged
