"""A user's own campaign: a TOML grid of scenarios x variants x seeds, each run a swarm configuration
built like `swarm up`'s (launch.scenario: a scenario file under the grid's ``[base]`` and then the
variant's overrides).

    name = "estimators-under-jamming"
    seeds = [1, 2, 3, 4, 5]            # or seeds = 5 (1..5), with first_seed = 1
    scenarios = ["gnss-jamming.toml"]  # relative to this file; none: the default swarm
    [base]                             # every run: any part of the configuration
    clock = { duration_s = 60 }
    [[variants]]
    name = "ekf"
    vehicle = { estimator = "ekf" }
    [[variants]]
    name = "ukf"
    vehicle = { estimator = "ukf" }

Run names are ``<variant>[-<scenario>]-seed<seed>``; a grid without variants has one, ``base``.
Every configuration is validated before any run starts (one-line error naming the run and field)."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from bus.config import build_config
from bus.errors import ConfigError
from launch.runspec import NAME, RunSpec
from launch.scenario import load_scenario, overlay

KEYS = {"name", "seeds", "first_seed", "scenarios", "base", "variants", "cpu_per_run"}


def load_grid(path: Path) -> tuple[str, list[RunSpec], float]:
    """(the campaign's name, its runs, the CPU one run needs) from a grid file."""
    try:
        grid = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(f"cannot read campaign {path}: {exc.strerror or exc}") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ConfigError(f"campaign {path} is not valid TOML: {exc}") from None
    unknown = sorted(set(grid) - KEYS)
    if unknown:
        raise ConfigError(f"campaign {path}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(KEYS))}")
    name = str(grid.get("name") or Path(path).stem)
    scenarios = [(Path(path).parent / s) for s in grid.get("scenarios", [])] or [None]
    variants = grid.get("variants") or [{"name": "base"}]
    specs = []
    for variant in variants:
        label = str(variant.get("name", "")) if isinstance(variant, dict) else ""
        if not label:
            raise ConfigError(f"campaign {path}: every [[variants]] needs a name")
        overrides = {k: v for k, v in variant.items() if k != "name"}
        for scenario in scenarios:
            base = overlay(load_scenario(scenario) if scenario else {}, grid.get("base", {}))
            for seed in _seeds(grid, path):
                run = f"{label}{'-' + scenario.stem if scenario and len(scenarios) > 1 else ''}-seed{seed}"
                config = overlay(overlay(base, overrides), {"name": run, "world": {"seed": seed}})
                specs.append(RunSpec(run, label, seed, _validated(config, run), overrides=overrides))
    return name, specs, float(grid.get("cpu_per_run", 2.0))


def _seeds(grid: dict[str, Any], path: Path) -> list[int]:
    seeds = grid.get("seeds", 1)
    if isinstance(seeds, int) and seeds >= 1:
        first = grid.get("first_seed", 1)
        return list(range(first, first + seeds))
    if isinstance(seeds, list) and seeds and all(isinstance(s, int) and s >= 0 for s in seeds):
        return list(dict.fromkeys(seeds))
    raise ConfigError(f"campaign {path}: seeds must be a count or a list of seeds, got {seeds!r}")


def _validated(config: dict[str, Any], run: str) -> dict[str, Any]:
    import re

    if not re.fullmatch(NAME, run):
        raise ConfigError(f"run {run!r}: names take letters, digits, '.', '_' and '-'")
    try:
        return build_config(config).model_dump(mode="json")
    except ConfigError as exc:
        raise ConfigError(f"run {run}: {exc}") from None
