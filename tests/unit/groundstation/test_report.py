"""The report: files exist, the HTML is self-contained, partial runs still report, statistics are right."""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.special import chdtri

from bus.config import SwarmConfig
from bus.mavlink_codec import StateEstimate
from bus.statistics import binned_rms
from groundstation.report import ReportError, write_report
from groundstation.report.rundata import load_run
from groundstation.report.stats import binned_nees, covariance_ellipse
from groundstation.rundir import RunDirectory
from groundstation.scoring import Scorer
from groundstation.summary import build_summary, build_timing

ZONE_EVENT = {"name": "jam1", "fault": "jam-gnss", "zone": {"center_m": [5.0, 0.0], "radius_m": 8.0}}


def _write_run(
    path: Path, rng: np.random.Generator, vehicles: int = 2, seconds: int = 10, uav: int | None = None
) -> None:
    """A run directory as the ground station writes it: two vehicles on circles, noisy estimates;
    vehicle ``uav`` climbing and estimating its height (the others' truth has none)."""
    run, scorer = RunDirectory(path), Scorer()
    for k in range(seconds * 10 + 1):
        t_us = k * 100_000
        for vid in range(1, vehicles + 1):
            angle = 0.1 * k + vid
            truth = np.array([10 * np.cos(angle) + 30 * vid, 10 * np.sin(angle), angle + np.pi / 2])
            height = 0.2 * k if vid == uav else None
            scorer.add_truth(vid, t_us, truth if height is None else np.append(truth, height))
            cov = np.diag([0.25, 0.16, 1e-4 if height is None else 0.36, 1e-4, 1e-4, 1e-3])
            cov[0, 1] = cov[1, 0] = 0.05
            err = rng.multivariate_normal(np.zeros(3), cov[:3, :3])
            z = -30.0 if height is None else -(height + err[2])  # NED
            est = StateEstimate(
                vid, t_us, np.array([*(truth[:2] + err[:2]), z]), truth[2], np.zeros(3), 0.0, cov, np.eye(6)
            )
            scorer.add_estimate(est)
        if k == 30:
            run.event("fault_added", t_us, **ZONE_EVENT)
        run.write_scores(scorer.release(t_us))
    run.event("fault_removed", seconds * 1_000_000, name="jam1")
    config = SwarmConfig(name="synthetic")
    run.write_json("config.json", config.model_dump(mode="json"))
    run.write_json("summary.json", build_summary(config, scorer, {}, {}, "complete"))
    run.write_json("timing.json", build_timing({}, seconds, 1.0))
    run.close()


@pytest.fixture()
def run_dir(tmp_path: Path) -> Path:
    _write_run(tmp_path / "run", np.random.default_rng(5))
    return tmp_path / "run"


def _references(page: str) -> list[str]:
    return re.findall(r"""(?:src|href)\s*=\s*['"]([^'"]*)['"]""", page)


def test_report_writes_figures_and_a_self_contained_page(run_dir):
    report = write_report(run_dir)
    assert [p.name for p in report.figures] == ["map.png", "error.png", "rmse.png", "nees.png", "nees_blocks.png"]
    for png in report.figures:
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000
    page = report.html.read_text()
    refs = _references(page)
    assert sum(r.startswith("data:image/png;base64,") for r in refs) == 5
    for ref in refs:  # nothing from the network; links only to files of this run
        assert ref.startswith("data:") or (not re.match(r"^[a-z]+:|^/|\.\.", ref) and (run_dir / ref).is_file()), ref
    assert "<script" not in page and "<link" not in page
    assert "jam-gnss" in page and report.problems == []


def test_killed_run_still_reports_and_says_what_is_missing(run_dir, tmp_path):
    killed = tmp_path / "killed"
    shutil.copytree(run_dir, killed)
    (killed / "summary.json").unlink()
    metrics = (killed / "metrics.csv").read_text()
    (killed / "metrics.csv").write_text(metrics[: len(metrics) // 2 + 7])  # cut in the middle of a line
    with (killed / "events.jsonl").open("a") as events:
        events.write('{"event": "vehicle_lo')
    report = write_report(killed)
    assert any("summary.json is missing" in p for p in report.problems)
    assert any(p.startswith("metrics.csv: 1 malformed") for p in report.problems)
    assert any(p.startswith("events.jsonl: 1 malformed") for p in report.problems)
    page = report.html.read_text()
    assert "summary.json is missing" in page and len(report.figures) == 5
    rows = load_run(killed).rows_of(1)
    assert np.all(np.diff(rows["t_s"]) > 0) and len(rows["t_s"]) < 101


def test_not_a_run_directory_is_a_clear_error(tmp_path):
    with pytest.raises(ReportError, match="does not exist"):
        write_report(tmp_path / "nothing")
    with pytest.raises(ReportError, match="not a run directory"):
        write_report(tmp_path)


def test_zones_come_from_fault_events(run_dir):
    zones = load_run(run_dir).zones()
    assert zones == [{"center_m": [5.0, 0.0], "radius_m": 8.0, "fault": "jam-gnss", "name": "jam1", "t_s": 3.0}]


def test_binned_rmse_of_known_errors():
    t = np.array([0.1, 0.2, 1.5, 1.7])
    centres, rmse = binned_rms(t, np.array([3.0, 4.0, 1.0, 1.0]), 1.0)
    np.testing.assert_allclose(centres, [0.5, 1.5])
    np.testing.assert_allclose(rmse, [np.sqrt(12.5), 1.0])


def test_nees_band_holds_95_percent_of_consistent_bins():
    """Chi-square(3) NEES from 8 independent vehicles: about 95% of bin means fall inside the band."""
    rng = np.random.default_rng(2)
    bins, vehicles, per_bin = 2000, 8, 5
    t = np.repeat(np.arange(bins * per_bin) / per_bin, vehicles)
    vehicle = np.tile(np.arange(vehicles), bins * per_bin)
    nees = rng.chisquare(3, size=t.size)
    _, mean, lower, upper = binned_nees(t, vehicle, nees, 1.0)
    assert len(mean) == bins
    np.testing.assert_allclose(lower, chdtri(24, 0.975) / 8)
    inside = np.mean((mean >= lower) & (mean <= upper))
    assert 0.93 < inside < 0.97
    assert np.mean((3 * mean >= lower) & (3 * mean <= upper)) < 0.05  # an over-confident swarm falls outside


def test_ellipse_outline_is_at_three_sigma():
    cov = np.array([[4.0, 1.5], [1.5, 1.0]])
    outline = covariance_ellipse(cov)
    np.testing.assert_allclose(np.einsum("ni,ij,nj->n", outline, np.linalg.inv(cov), outline), 9.0)


def test_a_large_swarm_shows_its_worst_vehicles_and_says_so(tmp_path):
    """Beyond a dozen vehicles the tables and per-vehicle figures show the worst, named as such, and
    the RMSE figure draws the vehicles as a band (a person can scan it; 250 lines would be noise)."""
    from groundstation.display import rmse_table
    from groundstation.report.figures import error_figure, rmse_figure
    from groundstation.report.panels import worst_vehicles
    from groundstation.shown import SHOWN

    _write_run(tmp_path / "big", np.random.default_rng(7), vehicles=30, seconds=4)
    data = load_run(tmp_path / "big")
    rmse = {v: float(np.sqrt(np.mean(data.rows_of(v)["err_pos_m"] ** 2))) for v in data.vehicles}
    shown, total = worst_vehicles(data, lambda rows: float(np.sqrt(np.mean(rows["err_pos_m"] ** 2))))
    assert total == 30 and shown == sorted(rmse, key=lambda v: -rmse[v])[:SHOWN]
    assert len(error_figure(data).axes) == SHOWN
    assert "the 12 of 30" in error_figure(data).legends[0].get_title().get_text()
    assert "30 vehicles: their median and 5-95 % band" in rmse_figure(data).axes[0].get_title()

    summary = json.loads((tmp_path / "big" / "summary.json").read_text())
    table = rmse_table(summary)
    by_rmse = sorted(summary["vehicles"], key=lambda v: -summary["vehicles"][v]["rmse_m"])[:SHOWN]
    assert list(table.columns[0].cells) == [*by_rmse, "swarm"]
    assert "12 of 30 vehicles with the largest RMSE" in table.caption


def test_a_small_swarm_shows_every_vehicle_in_numeric_order(run_dir):
    from groundstation.display import rmse_table

    summary = json.loads((run_dir / "summary.json").read_text())
    table = rmse_table(summary)
    assert list(table.columns[0].cells) == ["1", "2", "swarm"] and table.caption is None


def test_a_uav_run_adds_the_height_error_figure_and_a_level_one_says_nothing_of_it(run_dir, tmp_path):
    from groundstation.report.figures import height_figure

    _write_run(tmp_path / "uav", np.random.default_rng(3), vehicles=3, uav=2)
    report = write_report(tmp_path / "uav")
    assert "height.png" in [p.name for p in report.figures]
    data = load_run(tmp_path / "uav")
    (panel,) = height_figure(data).axes  # the UAV's only
    assert panel.get_ylabel() == "v2 [m]"
    errors = data.rows_of(2)["err_alt_m"]
    assert np.allclose(data.rows_of(2)["sigma_alt_m"], 0.6) and 0.45 < np.sqrt(np.mean(errors**2)) < 0.75
    assert np.isnan(data.rows_of(1)["err_alt_m"]).all()
    assert "Height" not in " ".join(write_report(run_dir).problems) and height_figure(load_run(run_dir)) is None
    assert "Height error" not in run_dir.joinpath("report.html").read_text()


def test_the_page_shows_the_heights_of_the_vehicles_that_estimate_theirs(tmp_path):
    from groundstation.report.page import _height_table

    consistency = {"block_anees": 0.87, "band_95": [0.07, 3.12]}
    summary = {"vehicles": {"2": {"altitude": {"rmse_m": 0.611, "max_error_m": 1.339, "anees": 0.865}}}}
    summary["vehicles"]["2"]["altitude"]["consistency"] = consistency
    summary["vehicles"]["1"] = {"rmse_m": 0.4}  # flies level: no height
    table = _height_table(summary)
    assert table.count("<tr>") == 2 and "<td>2</td><td>0.611</td><td>1.339</td><td>0.865</td>" in table
    assert "0.070-3.120" in table
    assert _height_table({"vehicles": {"1": {"rmse_m": 0.4}}}) == ""
