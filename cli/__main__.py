"""``python -m cli``: the `swarm` command."""

from cli.main import app

app()
