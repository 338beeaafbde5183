"""A campaign's results table: one row per run, ``results.parquet`` in the campaign folder (readable
with pandas, DuckDB, polars). Rows are kept in each run directory as they finish (``row.json``), so
a campaign that was stopped resumes from what is on disk, and the table is rebuilt from them, in the
campaign's run order (whatever order the runs finished in)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from campaign.rows import ROW_FILE
from launch.runspec import RunSpec

TABLE_FILE = "results.parquet"


def done_rows(folder: Path, specs: list[RunSpec]) -> dict[str, dict[str, Any]]:
    """The rows on disk of the runs of ``specs`` that completed (failed and missing ones are not)."""
    rows = {}
    for spec in specs:
        try:
            row = json.loads((folder / spec.name / ROW_FILE).read_text())
        except (OSError, ValueError):
            continue
        if isinstance(row, dict) and row.get("status") == "complete" and row.get("run") == spec.name:
            rows[spec.name] = row
    return rows


def write_table(folder: Path, specs: list[RunSpec], rows: dict[str, dict[str, Any]]) -> Path:
    """``results.parquet``: the rows of ``specs`` that exist, in ``specs``' order, every column in
    every row (absent: null)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    ordered = [rows[s.name] for s in specs if s.name in rows]
    columns = list(dict.fromkeys(key for row in ordered for key in row))
    table = pa.Table.from_pylist([{c: row.get(c) for c in columns} for row in ordered])
    path = folder / TABLE_FILE
    pq.write_table(table, path)
    return path


def read_table(path: Path) -> list[dict[str, Any]]:
    """The rows of a results table (a campaign folder or its results.parquet)."""
    import pyarrow.parquet as pq

    path = path / TABLE_FILE if path.is_dir() else path
    return pq.read_table(path).to_pylist()
