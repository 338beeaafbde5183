"""`swarm experiment cooperative` through real processes, small: 4 vehicles, 3 of them lose GNSS for
15 s; dead reckoning and split CI fly, the centralized reference runs on the same world."""

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.integration


def _experiment(out, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "cli", "experiment", "cooperative", "--out", str(out), "--quiet", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "COLUMNS": "200"},
    )


def test_cooperation_beats_dead_reckoning_and_the_reference_is_scored_alike(tmp_path):
    result = _experiment(
        tmp_path,
        "--seeds",
        "1",
        "--vehicles",
        "4",
        "--jammed",
        "3",
        "--jam-start",
        "5",
        "--jam",
        "15",
        "--variants",
        "dead-reckoning,ci-ekf",
        "--world",
        "ideal",
    )
    assert result.returncode == 0, result.stdout + result.stderr
    folder = tmp_path / "cooperative"
    rows = json.loads((folder / "experiment.json").read_text())["variants"]
    assert set(rows) == {"dead-reckoning", "ci-ekf", "centralized"}
    for row in rows.values():  # 3 jammed vehicles, 5-20 s every 0.2 s
        assert row["jammed_runs"] == 3 and row["samples"] == 3 * 76
    assert rows["ci-ekf"]["rmse_m"] < rows["dead-reckoning"]["rmse_m"] / 2
    assert rows["centralized"]["rmse_m"] < rows["dead-reckoning"]["rmse_m"] / 2
    for name in ("rmse_during_jam.png", "anees_during_jam.png"):
        assert (folder / name).stat().st_size > 10_000
    assert (folder / "ci-ekf-seed1" / "report.html").exists() and "centralized reference" in result.stdout


def test_a_bad_option_is_one_line_and_starts_nothing(tmp_path):
    for args, message in (
        (["--variants", "ci-ekf,kalman"], "unknown variant(s) kalman"),
        (["--vehicles", "4", "--jammed", "5"], "--jammed 5 is more than --vehicles 4"),
        (["--world", "mars"], "--world must be honest or ideal"),
    ):
        result = _experiment(tmp_path, *args)
        assert result.returncode == 1 and "Traceback" not in result.stderr
        assert result.stderr.startswith("swarm: error: ") and message in result.stderr, result.stderr
    assert not list(tmp_path.iterdir())
