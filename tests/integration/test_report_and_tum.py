"""`swarm up` ends with a report, and its TUM files re-check our RMSE with evo (an independent tool)."""

import math
import re

import pytest

from tests.integration.conftest import read_summary


def test_swarm_up_writes_the_report(three_vehicle_runs):
    run_dir = three_vehicle_runs[0]
    page = (run_dir / "report.html").read_text()
    for name in ("map", "error", "rmse", "nees"):
        assert (run_dir / "report" / f"{name}.png").stat().st_size > 10_000
    assert page.count("data:image/png;base64,") == 4
    assert not re.search(r"""(?:src|href)=['"](?:https?:|//)""", page)


def test_evo_ape_on_our_tum_files_matches_our_rmse(three_vehicle_runs):
    """evo's absolute pose error (translation, no alignment) per vehicle equals summary.json's RMSE."""
    file_interface = pytest.importorskip("evo.tools.file_interface")
    from evo.core import metrics, sync

    run_dir = three_vehicle_runs[0]
    summary = read_summary(run_dir)
    total_sq, total_n = 0.0, 0
    for vid, entry in summary["vehicles"].items():
        truth = file_interface.read_tum_trajectory_file(str(run_dir / "tum" / f"truth_v{vid}.tum"))
        est = file_interface.read_tum_trajectory_file(str(run_dir / "tum" / f"est_v{vid}.tum"))
        truth, est = sync.associate_trajectories(truth, est, max_diff=1e-4)
        ape = metrics.APE(metrics.PoseRelation.translation_part)
        ape.process_data((truth, est))
        rmse = ape.get_statistic(metrics.StatisticsType.rmse)
        assert est.num_poses == entry["samples"]
        assert rmse == pytest.approx(entry["rmse_m"], abs=2e-6)
        total_sq, total_n = total_sq + rmse ** 2 * est.num_poses, total_n + est.num_poses
    assert math.sqrt(total_sq / total_n) == pytest.approx(summary["swarm"]["rmse_m"], abs=2e-6)
