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


def test_the_papers_3d_cases_are_runs_beside_the_2d_ones(tmp_path):
    """The 3-D back end's cases fly the same flight over relief, each a run with its row, track and
    run.mcap, and the paper's figures 7 and 8 of them; full 3-D EKF-SLAM keeps every landmark, the
    adaptive range fewer; a flat-ground map over the relief loses the vehicle the triangulated map keeps."""
    cases = "ar-ekf-slam,3-D ar-ekf-slam,3-D ekf-slam,3-D flat-ground map"
    result = _experiment("--cases", cases, "--duration", "12", "--out", str(tmp_path))
    assert result.returncode == 0, result.stdout + result.stderr
    folder = tmp_path / "ar-slam"
    table = json.loads((folder / "experiment.json").read_text())["cases"]
    assert set(table) == set(cases.split(","))
    adaptive, full = table["3-D ar-ekf-slam"], table["3-D ekf-slam"]
    assert adaptive["range"] == "adaptive" and full["range"] == "all" and adaptive["terrain"] == "relief"
    assert adaptive["distance_m"] == full["distance_m"] > 50.0  # the same flight, 120 frames at 5 m/s
    assert adaptive["state_dim_max"] < full["state_dim_max"]
    assert adaptive["rmse_m"] < 1.0 and full["rmse_m"] < 1.0
    assert (
        table["3-D flat-ground map"]["rmse_m"] > 2.0
        and table["3-D flat-ground map"]["distance_m"] == full["distance_m"]
    )
    rows = pd.read_parquet(folder / "results.parquet").set_index("run")
    assert rows.loc["3-D-ekf-slam", "state_dim_max"] == full["state_dim_max"]
    figures = ("frame_time.png", "frame_time_3d.png", "track_3d.png")
    assert all((folder / figure).stat().st_size > 0 for figure in figures)
    for run in ("3-D-ar-ekf-slam", "3-D-ekf-slam"):  # each flight, its map and ellipsoids to open in Lichtblick
        assert (folder / run / "run.mcap").stat().st_size > 0 and (folder / run / "layout-lichtblick.json").exists()
