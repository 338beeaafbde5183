"""`swarm up` end to end: real router, world, ground station and vehicle processes over zenoh; it ends
with a report, and its TUM files re-check our RMSE with evo (an independent tool)."""

from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import time

import pytest

from tests.integration.conftest import (
    ESTIMATES_PER_S,
    processes_matching,
    read_summary,
    run_swarm,
    swarm_command,
    wait_for_metrics,
)

pytestmark = pytest.mark.integration
GNSS_SIGMA_M = 1.5  # the default SensorSpec.gnss_sigma_m


def test_fusion_beats_raw_gnss_on_every_vehicle(three_vehicle_runs):
    summary = read_summary(three_vehicle_runs[0])
    assert summary["status"] == "complete"
    assert set(summary["vehicles"]) == {"1", "2", "3"}
    for vid, vehicle in summary["vehicles"].items():
        assert vehicle["samples"] == 30 * ESTIMATES_PER_S + 1, vid  # every estimate sent from 0 to 30 s was scored
        assert vehicle["rmse_m"] < GNSS_SIGMA_M, vid


def test_same_seed_gives_identical_summary_and_metrics(three_vehicle_runs):
    a, b = three_vehicle_runs
    assert (a / "summary.json").read_text() == (b / "summary.json").read_text()
    assert (a / "metrics.csv").read_bytes() == (b / "metrics.csv").read_bytes()


def test_the_clock_tick_changes_no_estimate(three_vehicle_runs, tmp_path):
    """Lockstep ticks of 20 ms (one per cycle) and of the default 1 s (ten V2V latencies) give the
    same run: samples carry their stamps, vehicles cycle at 50 Hz in sim time either way, and a cycle
    waits for the neighbours' broadcasts its ranging pairs with."""
    result = run_swarm(
        tmp_path, "--vehicles", "3", "--duration", "30", "--seed", "11", "--name", "same", "--tick", "0.02"
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert (tmp_path / "same" / "metrics.csv").read_bytes() == (three_vehicle_runs[0] / "metrics.csv").read_bytes()
    assert (tmp_path / "same" / "summary.json").read_text() == (three_vehicle_runs[0] / "summary.json").read_text()
    assert not (tmp_path / "same" / "report.html").exists() and "swarm report" in result.stdout  # --no-report


def test_run_directory_is_complete(three_vehicle_runs):
    run = three_vehicle_runs[0]
    for name in ("config.json", "metrics.csv", "events.jsonl", "summary.json", "timing.json", "report.html"):
        assert (run / name).stat().st_size > 0, name
    for vid in (1, 2, 3):
        est, truth = (
            (run / "tum" / f"est_v{vid}.tum").read_text().splitlines(),
            (run / "tum" / f"truth_v{vid}.tum").read_text().splitlines(),
        )
        assert len(est) == len(truth) == 30 * ESTIMATES_PER_S + 1 and len(est[0].split()) == 8
    events = [json.loads(line)["event"] for line in (run / "events.jsonl").read_text().splitlines()]
    assert events.count("vehicle_joined") == 3 and "run_started" in events and events[-1] == "run_ended"


def test_killed_vehicle_is_logged_and_the_others_finish(tmp_path):
    process = subprocess.Popen(
        swarm_command(tmp_path, "--vehicles", "3", "--duration", "40", "--name", "kill"),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    run = tmp_path / "kill"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:  # wait until scoring has begun, then kill vehicle 2
        metrics = run / "metrics.csv"
        if metrics.exists() and metrics.stat().st_size > 20_000:
            break
        time.sleep(0.2)
    victims = processes_matching(f"{run}/vehicle.json --id 2")
    assert victims, "vehicle 2 process not found"
    os.kill(victims[0], signal.SIGKILL)
    output, _ = process.communicate(timeout=240)
    assert process.returncode != 0 and "vehicle-2 died" in output
    summary = read_summary(run)
    assert summary["status"] == "complete"
    assert summary["events"].get("vehicle_lost") == 1
    assert summary["vehicles"]["1"]["samples"] == summary["vehicles"]["3"]["samples"] == 40 * ESTIMATES_PER_S + 1
    assert summary["vehicles"]["2"]["samples"] < 40 * ESTIMATES_PER_S
    lost = [json.loads(line) for line in (run / "events.jsonl").read_text().splitlines()]
    assert any(e["event"] == "vehicle_lost" and e["vehicle"] == 2 for e in lost)


def test_sigint_shuts_everything_down_and_leaves_a_summary(tmp_path):
    process = subprocess.Popen(
        swarm_command(tmp_path, "--vehicles", "2", "--duration", "600", "--name", "stop"),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    run = tmp_path / "stop"
    wait_for_metrics(run, 2_000)
    process.send_signal(signal.SIGINT)
    process.communicate(timeout=30)
    assert read_summary(run)["status"] == "interrupted"
    assert processes_matching(f"{run}/config.json") == processes_matching(f"{run}/vehicle.json") == []


@pytest.mark.parametrize(
    "args, message",
    [
        (["--duration", "-5"], "duration_s"),
        (["--vehicles", "0"], "vehicles"),
        (["--mode", "warp"], "unknown mode"),
    ],
)
def test_bad_arguments_give_a_one_line_error(tmp_path, args, message):
    result = run_swarm(tmp_path, *args, timeout_s=60)
    assert result.returncode == 1
    assert message in result.stderr and "Traceback" not in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1
    assert not any(tmp_path.iterdir())


def test_realtime_mode_runs_and_reports_loop_timing(tmp_path):
    result = run_swarm(
        tmp_path, "--vehicles", "2", "--duration", "6", "--mode", "realtime", "--speed", "2", "--name", "rt"
    )
    assert result.returncode == 0, result.stdout + result.stderr
    summary = read_summary(tmp_path / "rt")
    timing = json.loads((tmp_path / "rt" / "timing.json").read_text())
    assert summary["status"] == "complete" and summary["mode"] == "realtime"
    for vid in ("1", "2"):
        assert summary["vehicles"][vid]["rmse_m"] < GNSS_SIGMA_M
        assert timing["vehicles"][vid]["cycles"] >= 6 * 50
        # each one's V2V frames go to the other on its own key (30 epochs in 6 s; half, for a busy machine)
        assert summary["vehicles"][vid]["v2v_fused"] >= 15
    assert 1.0 < timing["real_time_factor"] < 3.0  # paced near the requested speed of 2
    # the loops run under SCHED_FIFO at the default priority where this user may ask for it
    granted = 10 if _may_use_fifo(10) else 0
    assert [timing["vehicles"][vid]["loop_priority"] for vid in ("1", "2")] == [granted, granted]


def _may_use_fifo(priority: int) -> bool:
    """Whether this user may put a thread under SCHED_FIFO at ``priority``: asked from a throwaway thread."""
    import threading

    from vehicle.process.scheduling import ask_for_realtime_priority

    granted = []
    probe = threading.Thread(target=lambda: granted.append(ask_for_realtime_priority(priority)))
    probe.start()
    probe.join()
    return granted == [priority]


def test_swarm_up_writes_the_report(three_vehicle_runs):
    run_dir = three_vehicle_runs[0]
    page = (run_dir / "report.html").read_text()
    for name in ("map", "error", "rmse", "nees", "nees_blocks"):
        assert (run_dir / "report" / f"{name}.png").stat().st_size > 10_000
    assert page.count("data:image/png;base64,") == 5
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
        total_sq, total_n = total_sq + rmse**2 * est.num_poses, total_n + est.num_poses
    assert math.sqrt(total_sq / total_n) == pytest.approx(summary["swarm"]["rmse_m"], abs=2e-6)
