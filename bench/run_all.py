"""Runs every benchmark under bench/ (modules named bench_*.py with ``run(quick) -> list[Row]``),
prints one table and writes bench/results.json with the machine it was measured on.

Usage: python -m bench.run_all [--quick] [--only NAME]
"""

from __future__ import annotations

import importlib
import json
import os
import platform
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent


def machine() -> str:
    cpu = next(
        (
            line.split(":", 1)[1].strip()
            for line in Path("/proc/cpuinfo").read_text().splitlines()
            if line.startswith("model name")
        ),
        platform.processor() or platform.machine(),
    )
    return (
        f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, Python {platform.python_version()}"
    )


def table(rows: list[dict]) -> str:
    lines = ["| benchmark | case | metric | measured | target | met |", "| --- | --- | --- | ---: | --- | --- |"]
    for r in rows:
        met = {True: "yes", False: "**no**", None: "-"}[r["met"]]
        lines.append(
            f"| {r['benchmark']} | {r['case']} | {r['metric']} | {r['value']} {r['unit']} | {r['target']} | {met} |"
        )
    return "\n".join(lines)


def main() -> None:
    quick = "--quick" in sys.argv
    only = sys.argv[sys.argv.index("--only") + 1] if "--only" in sys.argv else None
    rows = []
    for path in sorted(ROOT.glob("bench_*.py")):
        if only and path.stem != f"bench_{only}":
            continue
        print(f"running {path.stem} ...", flush=True)
        rows += [r.as_dict() for r in importlib.import_module(f"bench.{path.stem}").run(quick)]
    path = ROOT / "results.json"
    if only and rows and path.exists():  # one benchmark re-measured: keep the other rows of the file
        rows = [r for r in json.loads(path.read_text())["rows"] if r["benchmark"] != rows[0]["benchmark"]] + rows
    text = table(rows)
    print(text)
    result = {"machine": machine(), "measured": time.strftime("%Y-%m-%d"), "quick": quick, "rows": rows, "table": text}
    (ROOT / "results.json").write_text(json.dumps(result, indent=2) + "\n")
    print(f"machine: {result['machine']}; wrote {ROOT / 'results.json'}")


if __name__ == "__main__":
    main()
