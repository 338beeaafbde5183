"""`swarm experiment ...`: the papers' experiments, each a folder of ordinary run directories (with
their reports) plus comparison figures and a JSON table (``experiments.vision_slam``)."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any, Optional

import typer

from bus.errors import SwarmlocError
from cli.errors import fail
from experiments.registry import EXPERIMENTS

OUT_HELP = "parent folder of the experiment's folder (<out>/<experiment>: the same command resumes it)"

LIVE_HELP = "serve each run's Foxglove WebSocket live view in turn, at --live-speed (docs: live view)"
LIVE_SPEED_HELP = "with --live: each lockstep run at most this many times real time (1: real time)"


def live_view(live: bool, host: str, port: int, speed: float = 1.0):
    """The runs' view with the live view on (its address checked now, a one-line error), or None. A
    lockstep run with a viewer is paced at ``speed`` times real time (``view.live_speed``; real time
    unless asked otherwise), so that each run of an experiment can be watched rather than flash by in
    seconds."""
    if not live:
        return None
    from bus.config import ViewConfig
    from launch.live import check_live_address

    try:
        check_live_address(host, port)
    except SwarmlocError as exc:
        fail(str(exc))
    return ViewConfig(live=True, live_host=host, live_port=port, live_speed=speed)


experiment_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Experiments from the papers, each a folder of ordinary runs plus comparison figures.",
)


def _experiment_command(name: str, entry) -> None:
    """`swarm experiment NAME`: the experiment's own options (experiments.registry) and the options
    every campaign takes, generated (a typer command with that signature)."""

    def command(**options: Any) -> None:
        _fly_experiment(name, options)

    own = [_option(p.name, p.default, p.help, p.minimum) for p in entry.params]
    command.__signature__ = inspect.Signature([*own, *CAMPAIGN_OPTIONS])
    command.__doc__ = entry.summary + " Flies as a campaign (docs: campaigns); the same command again resumes."
    experiment_app.command(name)(command)


def _option(
    name: str, default: Any, help_text: str, minimum: float | None = None, maximum: float | None = None
) -> inspect.Parameter:
    option = typer.Option(default, help=help_text, min=minimum, max=maximum)
    annotation = type(default) if default is not None else Optional[str]
    return inspect.Parameter(name, inspect.Parameter.KEYWORD_ONLY, default=option, annotation=annotation)


CAMPAIGN_OPTIONS = [
    inspect.Parameter(
        "out", inspect.Parameter.KEYWORD_ONLY, default=typer.Option(Path("runs"), help=OUT_HELP), annotation=Path
    ),
    _option("quiet", False, "no progress lines"),
    _option("scheduler", None, "a Dask scheduler's address (tcp://HOST:8786); default: a local cluster"),
    inspect.Parameter(
        "workers",
        inspect.Parameter.KEYWORD_ONLY,
        default=typer.Option(None, min=1, help="runs at once on the local cluster [default: from the cores]"),
        annotation=Optional[int],
    ),
    _option("shared", False, "with --scheduler: the workers see --out at the same path (else runs travel back)"),
    _option("timeout", 1800.0, "wall-clock seconds a run may take before it is ended (a failed run)", 1.0),
    _option("live", False, LIVE_HELP),
    _option("live_host", "127.0.0.1", "the live view's address"),
    _option("live_port", 8765, "the live view's port", 1),
    _option("live_speed", 1.0, LIVE_SPEED_HELP, 0.01, 10_000.0),
]


def _fly_experiment(name: str, options: dict[str, Any]) -> None:
    from rich.console import Console

    from bus.process import stop_on_signals
    from campaign.experiment import run_experiment
    from campaign.runner import Campaign
    from experiments.registry import EXPERIMENTS

    own = {p.name: options[p.name] for p in EXPERIMENTS[name].params}
    console = Console()
    say = (lambda text: None) if options["quiet"] else (lambda text: console.print(text, highlight=False))
    how = Campaign(
        scheduler=options["scheduler"],
        workers=options["workers"],
        timeout_s=options["timeout"],
        shared=options["shared"],
    )
    try:
        view = live_view(options["live"], options["live_host"], options["live_port"], options["live_speed"])
        folder, rows, lines = run_experiment(name, own, options["out"], how, stop=stop_on_signals(), view=view, say=say)
    except SwarmlocError as exc:
        fail(str(exc))
    for line in lines:
        console.print(line, highlight=False)
    failed = [r for r in rows if r.get("status") != "complete"]
    for row in failed:
        console.print(f"[red]swarm: {row['run']}: {row.get('exit_reason', row.get('status'))}[/red]")
    console.print(f"experiment: {folder} (results.parquet: one row per run)")
    if failed:
        raise typer.Exit(1)


for _name, _entry in EXPERIMENTS.items():
    _experiment_command(_name, _entry)
