"""What every experiment's ``conclude`` does with a campaign's rows: find the run directories of its
cases that completed, and write experiment.json."""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any, TypeVar

T = TypeVar("T")


def completed(rows: list[dict[str, Any]], cases: Iterable[T], folder: Path) -> dict[T, Path]:
    """{case: its run directory} for the ``cases`` (anything with a ``name``) whose run completed."""
    done = {row["run"] for row in rows if row.get("status") == "complete"}
    return {case: folder / case.name for case in cases if case.name in done}


def write_experiment(folder: Path, table: dict[str, Any]) -> None:
    (folder / "experiment.json").write_text(json.dumps(table, indent=2, sort_keys=True) + "\n")
