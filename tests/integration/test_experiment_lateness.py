"""`swarm experiment lateness` through real processes (the recipe's example of an experiment, and the
statistics of late inputs): every vehicle's IMU and odometry 0.3 s late for 55 of 60 s, on two seeds,
with the walk of overdue inputs and without it (the control the statistics must catch)."""

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.integration


def test_late_inputs_stay_honest_with_the_walk_and_not_without_it(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "cli", "experiment", "lateness", "--out", str(tmp_path), "--quiet"]
        + ["--seeds", "2", "--delays", "0.3", "--duration", "60", "--workers", "2"],
        capture_output=True,
        text=True,
        timeout=600,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert result.returncode == 0, result.stdout + result.stderr
    folder = tmp_path / "lateness"
    cases = json.loads((folder / "experiment.json").read_text())["cases"]
    walk, no_walk = cases["0.3 s, walk"], cases["0.3 s, no-walk"]
    assert walk["inside"] == "6 of 6", walk  # every vehicle of both seeds inside its NEES band
    assert no_walk["inside"] != "6 of 6" and no_walk["anees_max"] > walk["anees_max"], no_walk
    assert (folder / "anees_by_delay.png").stat().st_size > 10_000
    assert "0.3 s, walk" in result.stdout  # the line per case it prints
