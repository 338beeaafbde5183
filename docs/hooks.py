"""MkDocs hooks: the pages that are generated, not written. ``reference/cli.md`` from the typer app
(every command, argument and option with its help), ``reference/config.md`` from the pydantic
configuration models (every field with its type, default, bounds and description), and the
benchmark table of ``benchmarks.md`` from ``bench/results.json`` (the marker ``<!-- bench-table -->``),
the front ends' comparison of ``ar-slam.md`` from the same file (``<!-- front-end-table -->``), and the
faults page's table of fault kinds from their registry, bus.faults (``<!-- fault-table -->``).
Nothing here is pasted: change the code, and the docs follow at the next build."""

from __future__ import annotations

import json
import re
import sys
import typing
from pathlib import Path

from mkdocs.structure.files import File

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # mkdocs imports hooks by path: the project's packages are beside docs/
    sys.path.insert(0, str(ROOT))


def on_files(files, config):
    files.append(File.generated(config, "reference/cli.md", content=cli_reference()))
    files.append(File.generated(config, "reference/config.md", content=config_reference()))
    return files


def on_page_markdown(markdown: str, page, config, files) -> str:
    if "<!-- bench-table -->" in markdown:
        markdown = markdown.replace("<!-- bench-table -->", bench_table())
    if "<!-- swarm-table -->" in markdown:
        markdown = markdown.replace("<!-- swarm-table -->", swarm_table())
    if "<!-- front-end-table -->" in markdown:
        markdown = markdown.replace("<!-- front-end-table -->", front_end_table())
    for name in re.findall(r"<!-- bench-rows:([a-z ]+) -->", markdown):
        markdown = markdown.replace(f"<!-- bench-rows:{name} -->", bench_rows(name))
    if "<!-- fault-table -->" in markdown:
        markdown = markdown.replace("<!-- fault-table -->", fault_table())
    return markdown


def cli_reference() -> str:
    import typer.main
    from typer.cli import get_docs_for_click

    from cli.main import app

    command = typer.main.get_command(app)
    ctx = typer.Context(command)
    intro = (
        "# `swarm` command reference\n\nGenerated from the typer app (`cli/main.py`) at every docs build. "
        "Bad arguments give a one-line error and exit status 1.\n\n"
    )
    body = get_docs_for_click(obj=command, ctx=ctx, name="swarm", title="swarm")
    return intro + body.split("\n", 1)[1]  # its own title replaced by ours


def config_reference() -> str:
    from bus import config as c
    from bus import vehicle_config as vc
    from bus.estimators import ESTIMATORS
    from bus.sensors import SENSORS

    lines = [
        "# Configuration reference",
        "",
        "Generated from the pydantic models of `bus/config.py` (the datasheet and the world's extras in",
        "`bus/sensor_config.py`, the vehicle's settings in `bus/vehicle_config.py`) at every docs build. A",
        "scenario (TOML) or `config.json` sets any of these; `swarm config --out DIR` writes the resolved",
        "configuration of a scenario. Unknown keys and out-of-range values are refused with an error that",
        "names them.",
        "",
        "## Estimators",
        "",
        "| `vehicle.estimator` | what it is | module |",
        "| --- | --- | --- |",
    ]
    lines += [f"| `{name}` | {e.summary} | `{e.module}` |" for name, e in ESTIMATORS.items()]
    for title, model in (
        ("world", c.WorldConfig),
        ("world.sensor_truth", c.SensorTruth),
        ("sensors (the datasheet the vehicles are told)", c.SensorSpec),
        ("vehicle", c.VehicleConfig),
        ("vehicle.cooperation", vc.Cooperation),
        ("vehicle.adaptive", vc.AdaptiveNoise),
        ("vehicle.monitor", vc.NeighbourMonitor),
        ("vehicle.realtime", vc.RealtimeLoop),
        ("vehicle.ar", vc.ArSlamConfig),
        *((f"sensors.{sensor.topic} (an added sensor)", sensor.Spec) for sensor in SENSORS),
        ("clock", c.ClockConfig),
        ("view (run.mcap and the live view)", c.ViewConfig),
        ("bus", c.BusConfig),
    ):
        lines += ["", f"## `{title}`", ""] + _model_table(model)
    lines += ["", "Faults are described on the [faults page](../faults.md)."]
    return "\n".join(lines) + "\n"


def _model_table(model) -> list[str]:
    rows = ["| key | type | default | bounds | description |", "| --- | --- | --- | --- | --- |"]
    for name, field in model.model_fields.items():
        bounds = ", ".join(
            f"{op} {getattr(m, attr)}"
            for m in field.metadata
            for attr, op in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"), ("max_length", "len <="))
            if getattr(m, attr, None) is not None
        )
        default = "required" if field.is_required() else f"`{field.get_default(call_default_factory=True)!r}`"
        description = (field.description or "").replace("|", "\\|").replace("\n", " ")
        rows.append(f"| `{name}` | {_type_name(field.annotation)} | {default} | {bounds} | {description} |")
    return rows


def _type_name(annotation) -> str:
    if typing.get_origin(annotation) is typing.Literal:
        return " \\| ".join(f"`{v}`" for v in typing.get_args(annotation))
    text = getattr(annotation, "__name__", None) or str(annotation).replace("typing.", "")
    return f"`{text}`".replace("|", "\\|")


def fault_table() -> str:
    """Every fault kind of the registry (bus.faults.KINDS): who applies it, its own fields, its effect."""
    from bus.faults import KINDS, FaultBase
    from bus.faults.base import APPLIERS

    lines = ["| kind | applied by | fields | effect |", "| --- | --- | --- | --- |"]
    for kind in KINDS:
        fields = []
        for name, field in kind.model_fields.items():
            if name in FaultBase.model_fields or name == "kind":
                continue
            values = typing.get_args(field.annotation) if typing.get_origin(field.annotation) is typing.Literal else ()
            fields.append(f"`{name}`" + (f" ({', '.join(values)})" if values else ""))
        effect = kind.effect.replace("|", "\\|")
        lines.append(f"| `{kind.kind_name()}` | {APPLIERS[kind.applied_by]} | {', '.join(fields)} | {effect} |")
    return "\n".join(lines)


def bench_table() -> str:
    path = ROOT / "bench" / "results.json"
    if not path.exists():
        return "*No `bench/results.json` yet: run `make bench`.*"
    results = json.loads(path.read_text())
    lines = [
        f"Measured on {results.get('machine', 'an unknown machine')}, {results.get('measured', '')}"
        + (" (quick run)" if results.get("quick") else "")
        + ". Generated from `bench/results.json` at every docs build.",
        "",
        "| benchmark | case | metric | measured | target | met |",
        "| --- | --- | --- | ---: | --- | --- |",
    ]
    for r in results["rows"]:
        met = {True: "yes", False: "**no**", None: "-"}[r["met"]]
        case = str(r["case"]).replace("|", "\\|")
        lines.append(
            f"| {r['benchmark']} | {case} | {r['metric']} | {r['value']} {r['unit']} | {r['target']} | {met} |"
        )
    return "\n".join(lines)


def bench_rows(benchmark: str) -> str:
    """The rows of one benchmark of ``bench/results.json`` (``<!-- bench-rows:NAME -->``)."""
    path = ROOT / "bench" / "results.json"
    rows = [r for r in json.loads(path.read_text())["rows"] if r["benchmark"] == benchmark] if path.exists() else []
    if not rows:
        return f"*No {benchmark} rows in `bench/results.json` yet: run `make bench`.*"
    lines = ["| case | metric | measured | target | met |", "| --- | --- | ---: | --- | --- |"]
    for r in rows:
        met = {True: "yes", False: "**no**", None: "-"}[r["met"]]
        lines.append(f"| {r['case']} | {r['metric']} | {r['value']} {r['unit']} | {r['target']} | {met} |")
    return "\n".join(
        lines + ["", f"Generated from `bench/results.json` (`bench/bench_{benchmark}.py`) at every docs build."]
    )


def front_end_table() -> str:
    """The front ends benchmark's rows (bench_front_ends.py) as one line per front end."""
    path = ROOT / "bench" / "results.json"
    rows = [r for r in json.loads(path.read_text())["rows"] if r["benchmark"] == "front ends"] if path.exists() else []
    if not rows:
        return "*No front-end rows in `bench/results.json` yet: run `python -m bench.run_all --only front_ends`.*"
    metrics = list(dict.fromkeys(r["metric"] for r in rows))
    by_case: dict[str, dict[str, str]] = {}
    for r in rows:
        by_case.setdefault(r["case"], {})[r["metric"]] = f"{r['value']} {r['unit']}".strip()
    lines = ["| front end, frames | " + " | ".join(metrics) + " |", "| --- |" + " ---: |" * len(metrics)]
    lines += [
        f"| {case} | " + " | ".join(values.get(m, "") for m in metrics) + " |" for case, values in by_case.items()
    ]
    return "\n".join(
        lines + ["", "Generated from `bench/results.json` (`bench/bench_front_ends.py`) at every docs build."]
    )


def swarm_table() -> str:
    """The swarm rows' details (bench_swarm.py), one line per case."""
    path = ROOT / "bench" / "results.json"
    if not path.exists():
        return ""
    seen, lines = (
        set(),
        [
            "| case | vehicles | sim s | RTF | floor [s] | overruns | jitter p99 [ms] | cycle p99 [ms] "
            "| loop | vehicle RSS [MB] | swarm RMSE [m] | ANEES | target |",
            "| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- | ---: | ---: | ---: | --- |",
        ],
    )
    for row in json.loads(path.read_text())["rows"]:
        d = row.get("details") or {}
        key = (d.get("label"), d.get("vehicles"))
        if row["benchmark"] != "swarm" or not d.get("label") or key in seen:
            continue
        seen.add(key)
        floor = d.get("floor_wall_s")
        lockstep = d.get("mode") == "lockstep"
        jitter = "-" if lockstep else f"{d.get('jitter_p99_us', 0) / 1000:.2f}"
        loop = "-" if lockstep else f"SCHED_FIFO {d['loop_priority']}" if d.get("loop_priority") else "fair scheduler"
        lines.append(
            f"| {d['label']} | {d['vehicles']} | {d['sim_s']} | {d['real_time_factor']:.2f}x "
            f"| {'-' if floor is None else floor} | {100 * d['overrun_rate']:.2f}% | {jitter} "
            f"| {d['cycle_p99_us'] / 1000:.2f} | {loop} | {d['vehicle_rss_mb_max']} | {d['swarm_rmse_m']} "
            f"| {d['swarm_anees']} | {d['target']} |"
        )
    return "\n".join(lines)
