"""``python -m cli``: the `swarm` command."""

from cli.main import app

if __name__ == "__main__":  # imported again, not run, in every child the forkserver starts (launch.children)
    app()
