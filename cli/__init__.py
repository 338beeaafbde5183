"""The top of the top floor: the `swarm` command (``cli.main``) and its sub-commands. Typer commands
only: they parse options, then hand over to ``launch`` (start a swarm), ``experiments`` or one
process's entry point. May import every package; nothing imports it."""
