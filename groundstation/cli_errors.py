"""How every `swarm` command reports a known error: one line on stderr, exit status 1."""

from __future__ import annotations

from typing import NoReturn

import typer


def fail(message: str) -> NoReturn:
    typer.echo(f"swarm: error: {message}", err=True)
    raise typer.Exit(1)
