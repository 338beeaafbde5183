"""The `swarm` command's entry point. A command that starts a swarm (`swarm up`, `swarm replay
mrclam`) first starts the server its processes are forked from (launch.children.warm_up), so that
the server imports what they run while this process imports the command line (on two cores the
two imports overlap: about 0.2 s sooner per run). Every other command starts as before."""

from __future__ import annotations

import sys

LAUNCHING = (("up",), ("replay", "mrclam"))


def launches_a_swarm(argv: list[str]) -> bool:
    """Whether the command line ``argv`` (without the program name) starts a swarm."""
    if "--help" in argv:
        return False
    return any(tuple(argv[: len(command)]) == command for command in LAUNCHING)


def main() -> None:
    if launches_a_swarm(sys.argv[1:]):
        from launch.children import warm_up

        warm_up()
    from cli.main import app

    app()
