"""One run of an experiment or a campaign: its name (its run directory's), the group it belongs to
(a variant, a condition), its seed and the configuration it flies (``bus.config.build_config``'s
input), and optionally a function that measures what the experiment needs from the finished run
(``"module:function"``, called with the run directory; its dict of numbers goes into the run's row of
the results table) and one that flies it instead of a swarm of real processes (``runner``, called
with the spec and its run directory: a computation in one process, such as a centralized
reference). Plain data: it crosses to a campaign's workers as JSON."""

from __future__ import annotations

import importlib
import json
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from bus.errors import ConfigError

NAME = r"^[A-Za-z0-9_.\-]{1,120}$"


@dataclass(frozen=True)
class RunSpec:
    name: str
    variant: str
    seed: int
    config: dict[str, Any] = field(default_factory=dict)
    measure: str | None = None
    overrides: dict[str, Any] = field(default_factory=dict)  # what a campaign grid set (for the table)
    runner: str | None = None
    report: bool = False  # write the run's report (report.html) when it completes, as `swarm up` does

    def to_json(self) -> str:
        return json.dumps(asdict(self), sort_keys=True)

    @staticmethod
    def from_json(text: str) -> RunSpec:
        data = json.loads(text)
        return RunSpec(**data)


def check_unique(specs: list[RunSpec]) -> None:
    """ConfigError (one line) when two runs share a name: their run directories would."""
    seen: set[str] = set()
    for spec in specs:
        if spec.name in seen:
            raise ConfigError(f"two runs are named {spec.name!r}")
        seen.add(spec.name)


def measured(spec: RunSpec, run_dir: Path) -> dict[str, Any]:
    """What the spec's measure function finds in its run directory ({} without one)."""
    return resolve(spec.measure)(run_dir) if spec.measure else {}


def resolve(path: str) -> Any:
    """The function ``"module:function"`` names."""
    module, _, function = path.partition(":")
    return getattr(importlib.import_module(module), function)
