"""How every `swarm` command reports a known error: one line on stderr, exit status 1; and the help of
the options that several commands share."""

from __future__ import annotations

from typing import NoReturn

import typer


def fail(message: str) -> NoReturn:
    typer.echo(f"swarm: error: {message}", err=True)
    raise typer.Exit(1)


REPORT_HELP = (
    "write report.html and report/*.png at the end; --no-report skips them (a Monte Carlo batch "
    "or a CI loop that reads summary.json), `swarm report RUN` writes them later"
)
