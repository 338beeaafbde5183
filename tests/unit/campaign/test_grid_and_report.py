"""A campaign's pure parts: a user's grid becomes validated runs named by variant, scenario and seed
(a bad grid is a one-line error naming the run and field); the report's 95 % interval is Student's
over the seeds; the results table keeps every column and the campaign's run order."""

import math

import numpy as np
import pytest

from bus.errors import ConfigError
from bus.statistics import interval
from campaign.grid import load_grid
from campaign.report import by_variant
from campaign.table import done_rows, read_table, write_table
from launch.runspec import RunSpec


def _grid(tmp_path, text: str):
    path = tmp_path / "g.toml"
    path.write_text(text)
    return path


def test_a_grid_is_scenarios_times_variants_times_seeds_each_validated(tmp_path):
    (tmp_path / "a.toml").write_text("[world]\nvehicles = 3\n")
    (tmp_path / "b.toml").write_text("[world]\nvehicles = 4\n")
    path = _grid(
        tmp_path,
        'name = "g"\nseeds = [4, 7]\nscenarios = ["a.toml", "b.toml"]\n[base]\nclock = { duration_s = 12 }\n'
        '[[variants]]\nname = "ekf"\n[[variants]]\nname = "ukf"\nvehicle = { estimator = "ukf" }\n',
    )
    name, specs, cpu = load_grid(path)
    assert name == "g" and cpu == 2.0 and len(specs) == 8
    assert [s.name for s in specs[:4]] == ["ekf-a-seed4", "ekf-a-seed7", "ekf-b-seed4", "ekf-b-seed7"]
    ukf = [s for s in specs if s.variant == "ukf"]
    assert all(
        s.config["vehicle"]["estimator"] == "ukf" and s.overrides == {"vehicle": {"estimator": "ukf"}} for s in ukf
    )
    assert {s.config["world"]["vehicles"] for s in specs} == {3, 4} and {s.seed for s in specs} == {4, 7}
    assert all(s.config["clock"]["duration_s"] == 12 and s.config["world"]["seed"] == s.seed for s in specs)


@pytest.mark.parametrize(
    "text, message",
    [
        ('seeds = 2\n[[variants]]\nname = "x"\nvehicle = { estimator = "kalman" }\n', "run x-seed1: invalid"),
        ("seeds = 0\n", "seeds must be a count"),
        ("seed = 3\n", "unknown key(s) seed"),
        ('[[variants]]\nvehicle = { estimator = "ukf" }\n', "needs a name"),
        ('[[variants]]\nname = "a b"\n', "names take letters"),
        ("seeds = [\n", "not valid TOML"),
    ],
)
def test_a_bad_grid_is_a_one_line_error_naming_what_is_wrong(tmp_path, text, message):
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace(")", r"\)")) as caught:
        load_grid(_grid(tmp_path, text))
    assert "\n" not in str(caught.value)


def test_the_interval_is_students_over_the_seeds_and_covers_the_mean_as_often_as_it_says():
    rng = np.random.default_rng(5)
    covered = 0
    for _ in range(2000):
        mean, half, n = interval(list(rng.normal(1.0, 0.3, 5)))
        covered += abs(mean - 1.0) <= half
    assert n == 5 and 0.93 <= covered / 2000 <= 0.97
    assert interval([2.0])[0] == 2.0 and math.isnan(interval([2.0])[1]) and interval([])[2] == 0


def test_only_completed_runs_count_per_variant():
    rows = [
        {"variant": "a", "status": "complete", "rmse_m": 1.0},
        {"variant": "a", "status": "complete", "rmse_m": 3.0},
        {"variant": "a", "status": "failed", "rmse_m": 100.0},
        {"variant": "b", "status": "failed"},
    ]
    table = by_variant(rows, ("rmse_m",))
    assert table["a"]["rmse_m"][0] == 2.0 and table["a"]["rmse_m"][2] == 2 and table["b"]["rmse_m"][2] == 0


def test_the_table_keeps_every_column_and_the_campaigns_order_and_resuming_reads_completed_runs(tmp_path):
    import json

    specs = [RunSpec(f"r{k}", "v", k) for k in range(3)]
    rows = {"r2": {"run": "r2", "status": "complete", "x": 1.5}, "r0": {"run": "r0", "status": "failed", "y": "z"}}
    write_table(tmp_path, specs, rows)
    assert read_table(tmp_path) == [{"run": "r0", "status": "failed", "y": "z", "x": None},
                                    {"run": "r2", "status": "complete", "y": None, "x": 1.5}]  # fmt: skip
    for name, row in rows.items():
        (tmp_path / name).mkdir()
        (tmp_path / name / "row.json").write_text(json.dumps(row))
    assert set(done_rows(tmp_path, specs)) == {"r2"}  # the failed run is flown again
