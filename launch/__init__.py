"""The top floor's launcher: starts a swarm's processes (router, world, ground station, vehicles) as
subprocesses and watches them, reads scenarios, draws chaos timelines and sets up data-set replays.
Used by the `swarm` command (``cli``) and the experiments; imports the packages below it, never them."""
