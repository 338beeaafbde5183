"""`swarm experiment ar-slam` as a campaign: each case a run that feeds its estimator in one process
(no bus), its table row and track in its run directory, and experiment.json and the figures from the
cases that completed."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pandas as pd
import pytest

pytestmark = pytest.mark.integration


def _experiment(*args: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "cli", "experiment", "ar-slam", "--quiet", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=300, env={**os.environ, "COLUMNS": "200"})


def test_each_case_is_a_run_and_the_table_is_built_from_them(tmp_path):
    result = _experiment("--cases", "ekf-slam,ar-ekf-slam", "--duration", "12", "--out", str(tmp_path))
    assert result.returncode == 0, result.stdout + result.stderr
    folder = tmp_path / "ar-slam"
    table = json.loads((folder / "experiment.json").read_text())
    assert table["seed"] == 3 and set(table["cases"]) == {"ekf-slam", "ar-ekf-slam"}
    for name, case in table["cases"].items():
        assert case["frames"] >= 100 and case["rmse_m"] < 1.0, (name, case)
    assert table["cases"]["ekf-slam"]["range"] == "all" and table["cases"]["ar-ekf-slam"]["range"] == "adaptive"
    rows = pd.read_parquet(folder / "results.parquet").set_index("run")
    assert list(rows.index) == ["ekf-slam", "ar-ekf-slam"] and set(rows["status"]) == {"complete"}
    assert rows.loc["ekf-slam", "rmse_m"] == table["cases"]["ekf-slam"]["rmse_m"]  # the table's numbers, per run
    assert all((folder / figure).stat().st_size > 0 for figure in ("frame_time.png", "x_error.png"))


def test_an_unknown_case_is_refused_by_name(tmp_path):
    result = _experiment("--cases", "ekf-slam,warp-drive", "--out", str(tmp_path))
    assert result.returncode != 0 and "warp-drive" in result.stderr and "Traceback" not in result.stderr
