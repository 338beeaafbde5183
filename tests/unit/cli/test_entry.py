"""Which command lines start the forkserver before the command line interface is imported."""

import pytest

from cli.entry import launches_a_swarm


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["up"], True),
        (["up", "scenarios/demo.toml", "--vehicles", "3"], True),
        (["replay", "mrclam", "data"], True),
        (["replay", "calibrate", "data"], False),
        (["up", "--help"], False),
        (["vehicle", "--config", "v.json", "--id", "1"], False),
        (["experiment", "cooperative"], False),
        ([], False),
    ],
)
def test_only_commands_that_start_a_swarm_warm_the_forkserver(argv, expected):
    assert launches_a_swarm(argv) is expected
