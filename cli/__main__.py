"""``python -m cli``: the `swarm` command."""

from cli.entry import main

if __name__ == "__main__":  # imported again, not run, in every child the forkserver starts (launch.children)
    main()
