"""Camera vehicles through real processes (lockstep): the world renders each vehicle's frames from
the terrain and publishes them in its sensor batches; `ekf-slam` vehicles with GNSS jammed for the
whole run map the ground, close the loop, and beat dead reckoning flown on the same seed."""

import csv
import json
import math
import os
import socket
import subprocess
import sys

import pytest

from tests.integration.conftest import ESTIMATES_PER_S, read_summary

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """`swarm experiment vision-slam`: a circle and a figure-8 UAV, GNSS jammed all flight, 60 s,
    flown with ekf-slam and with dead reckoning on the same seed, each served live in turn (paced at
    1,000 times real time: as fast as the runs go, where the default real time would take 2 minutes)."""
    out = tmp_path_factory.mktemp("experiment")
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    command = [sys.executable, "-m", "cli", "experiment", "vision-slam", "--out", str(out), "--seed", "3", "--quiet"]
    result = subprocess.run(
        [*command, "--live", "--live-port", str(port), "--live-speed", "1000"],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "COLUMNS": "200"},
    )
    assert result.returncode == 0, result.stdout + result.stderr
    folder = out / "vision-slam"
    return {"slam": folder / "slam", "dr": folder / "dead-reckoning", "folder": folder, "port": port}


def _sigma_xy(run, vehicle: int) -> dict[float, float]:
    with (run / "metrics.csv").open() as handle:
        return {
            float(r["t_s"]): math.hypot(float(r["sigma_x_m"]), float(r["sigma_y_m"]))
            for r in csv.DictReader(handle)
            if r["vehicle"] == str(vehicle)
        }


def test_camera_vehicles_map_the_ground_they_fly_over(runs):
    summary = read_summary(runs["slam"])
    assert summary["status"] == "complete"
    for vid in ("1", "2"):
        vehicle = summary["vehicles"][vid]
        assert vehicle["samples"] == 60 * ESTIMATES_PER_S + 1
        assert vehicle["camera_frames_used"] == 60 * 10 + 1 and vehicle["landmarks"] >= 50
    assert "garbage_frame" not in summary["rejected"]["by_reason"]


def test_the_loop_closure_shrinks_the_pose_covariance(runs):
    """The circle (vehicle 1) comes back over its start after ~31 s, with no GNSS at all."""
    sigma = _sigma_xy(runs["slam"], 1)
    grown = max(s for t, s in sigma.items() if 20.0 <= t <= 29.0)
    closed = min(s for t, s in sigma.items() if 30.0 <= t <= 33.0)
    assert closed < 0.6 * grown


def test_slam_beats_dead_reckoning_on_the_same_seed(runs):
    slam, dr = read_summary(runs["slam"])["swarm"], read_summary(runs["dr"])["swarm"]
    assert slam["rmse_m"] < dr["rmse_m"] / 3


def test_the_experiment_writes_both_runs_the_maps_and_the_comparison(runs):
    folder = runs["folder"]
    table = json.loads((folder / "experiment.json").read_text())
    assert (
        table["slam"]["vehicles"]["1"]["landmarks"] >= 50
        and table["dead-reckoning"]["vehicles"]["1"]["landmarks"] is None
    )
    for name in ("error_vs_dead_reckoning.png", "nees_vs_dead_reckoning.png"):
        assert (folder / name).stat().st_size > 10_000
    for vid in (1, 2):
        landmarks = json.loads((runs["slam"] / f"map_v{vid}.json").read_text())
        assert landmarks["landmarks"] == read_summary(runs["slam"])["vehicles"][str(vid)]["landmarks"]
        assert landmarks["t_s"] == 60.0  # the final map
    assert not list(runs["dr"].glob("map_v*.json")) and (runs["slam"] / "report" / "map.png").exists()


def test_a_missing_orthophoto_is_one_line_before_anything_starts(tmp_path):
    scenario = tmp_path / "ortho.toml"
    scenario.write_text('[world]\nterrain = "/no/such/ortho.png"\n[sensors]\ncamera_rate_hz = 10\n')
    result = subprocess.run(
        [sys.executable, "-m", "cli", "up", str(scenario), "--quiet", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1 and "Traceback" not in result.stderr
    assert result.stderr.strip() == "swarm: error: terrain image /no/such/ortho.png does not exist (world.terrain)"
    assert not list(tmp_path.glob("run*"))  # no run was started


def test_the_recording_draws_each_slam_vehicles_map_as_it_reports_it(runs):
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    with (runs["slam"] / "run.mcap").open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        maps = [d for _, _, _, d in reader.iter_decoded_messages(topics=["/landmarks"])]
    last = {e.id: e for update in maps for e in update.entities}  # the newest map of each vehicle
    assert set(last) == {"landmarks-1", "landmarks-2"}
    for vid in (1, 2):
        final = json.loads((runs["slam"] / f"map_v{vid}.json").read_text())
        assert len(last[f"landmarks-{vid}"].lines[0].points) == 24 * final["landmarks"]  # 12 segments each


def test_the_recording_lays_the_terrain_the_cameras_saw_under_the_scene(runs):
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    glb = (runs["slam"] / "terrain.glb").read_bytes()
    with (runs["slam"] / "run.mcap").open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        updates = [d for _, _, _, d in reader.iter_decoded_messages(topics=["/terrain"])]
    assert len(updates) == 1  # once at the start (again only for a live viewer that subscribes)
    (entity,) = updates[0].entities
    (model,) = entity.models
    assert entity.id == "terrain" and model.media_type == "model/gltf-binary" and model.data == glb
    assert glb[:4] == b"glTF"


def test_each_run_of_the_experiment_was_served_live_in_turn(runs):
    for flight in ("slam", "dr"):
        view = json.loads((runs[flight] / "config.json").read_text())["view"]
        assert view["live"] and view["live_port"] == runs["port"] and view["live_speed"] == 1000.0
        log = (runs[flight] / "logs" / "groundstation.log").read_text()
        assert f"live view: ws://127.0.0.1:{runs['port']}" in log and "did not start" not in log
