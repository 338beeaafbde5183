"""The recording's pure parts: the 3-sigma ellipse, the file name a restarted ground station takes,
the Foxglove and Lichtblick layouts in deploy/ kept equal to their generator, accepted by
Lichtblick's import (tests.viewer_rules) and framing the swarm."""

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from groundstation.layout import FOXGLOVE_FILE, LICHTBLICK_FILE, framing, swarm_layouts
from groundstation.recording_start import recording_path
from groundstation.scene_primitives import ellipse_xy
from tests.viewer_rules import lichtblick_layout_errors

ROOT = Path(__file__).resolve().parents[3]


def test_the_ellipse_is_three_sigma_along_the_covariance_eigenvectors():
    angle = 0.4
    R = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    covariance = R @ np.diag([4.0, 1.0]) @ R.T
    ring = ellipse_xy(np.array([10.0, -2.0]), covariance) - np.array([10.0, -2.0])
    along = ring @ R  # in the eigenvector frame
    assert abs(np.max(np.abs(along[:, 0])) - 6.0) < 1e-9 and abs(np.max(np.hypot(*ring.T)) - 6.0) < 1e-9
    assert abs(np.max(np.abs(along[:, 1])) - 3.0) < 0.05
    assert np.allclose((along[:, 0] / 6.0) ** 2 + (along[:, 1] / 3.0) ** 2, 1.0)


def test_a_restarted_ground_station_records_to_a_new_file(tmp_path):
    assert recording_path(tmp_path).name == "run.mcap"
    (tmp_path / "run.mcap").write_bytes(b"")
    assert recording_path(tmp_path).name == "run.1.mcap"


def test_the_layouts_in_the_repository_are_the_generated_ones_and_name_our_channels():
    from bus.config import WorldConfig

    generated = swarm_layouts(WorldConfig())
    for name, app in ((FOXGLOVE_FILE, "foxglove"), (LICHTBLICK_FILE, "lichtblick")):
        text = (ROOT / "deploy" / f"{app}-layout.json").read_text()
        assert text == generated[name], name
        layout = json.dumps(json.loads(text))
        topics = ("/scene", "/vehicle/5/metrics.err_pos_m", "/vehicle/1/metrics.nees", "/events", "/ranging")
        topics += (
            "/terrain",
            "/vehicle/3/health.gnss_test_ratio",
            "/vehicle/2/loop.overruns",
            "/swarm.rms_error_m",
        )
        for topic in topics:
            assert topic in layout, (name, topic)


def test_the_lichtblick_layout_is_what_its_import_accepts_and_every_series_reads_receive_time():
    from bus.config import WorldConfig

    data = json.loads(swarm_layouts(WorldConfig(vehicles=8))[LICHTBLICK_FILE])
    assert lichtblick_layout_errors(data) == []
    assert lichtblick_layout_errors(json.loads((ROOT / "deploy" / "foxglove-layout.json").read_text()))  # the control
    plots = [c for key, c in data["configById"].items() if key.startswith("Plot!")]
    assert plots and all(p["timestampMethod"] == "receiveTime" for c in plots for p in c["paths"])
    assert {p["label"] for p in plots[0]["paths"]} >= {f"v{v}" for v in range(1, 9)}
    foxglove = json.loads(swarm_layouts(WorldConfig(vehicles=8))[FOXGLOVE_FILE])
    assert '"timestampMethod": "receiveTime"' in json.dumps(foxglove) and "receiveTime" in json.dumps(foxglove)


def test_a_large_swarm_plots_its_aggregates_not_hundreds_of_lines():
    from bus.config import WorldConfig
    from bus.statistics import chi2_band

    data = json.loads(swarm_layouts(WorldConfig(vehicles=250))[LICHTBLICK_FILE])
    assert lichtblick_layout_errors(data) == []
    plots = {key: c for key, c in data["configById"].items() if key.startswith("Plot!")}
    values = {p["value"] for c in plots.values() for p in c["paths"]}
    assert values >= {"/swarm.rms_error_m", "/swarm.max_error_m", "/swarm.mean_nees"}
    assert not any(v.startswith("/vehicle/") for v in values) and len(values) <= 6
    low, high = chi2_band(3, runs=250)  # the band of a mean of 250 NEES, not of one
    assert f"{low:.4f}" in values and f"{high:.4f}" in values


def test_the_swarm_record_sums_up_the_vehicles_scored_at_a_stamp():
    from types import SimpleNamespace

    from groundstation.plot_records import swarm_records

    def score(vid: int, error: float, nees: float) -> SimpleNamespace:  # what a Score offers the record
        return SimpleNamespace(vehicle_id=vid, stamp_us=1_000_000, position_error_m=error, nees=nees)

    [(stamp, record)] = swarm_records([score(1, 3.0, 2.0), score(2, 4.0, float("nan")), score(3, 0.0, 4.0)])
    assert stamp == 1_000_000 and record["max_error_m"] == 4.0 and record["vehicles"] == 3
    assert record["rms_error_m"] == pytest.approx(math.sqrt(25.0 / 3.0)) and record["mean_nees"] == 3.0


@pytest.mark.parametrize("vehicles", [1, 5, 20, 50])
def test_the_camera_frames_every_start_pad_and_the_trajectories_around_them(vehicles):
    """Looking down the camera's axis from its distance with its field of view, every point within a
    trajectory's reach (two radii) of a start pad is in view."""
    from bus.config import WorldConfig
    from bus.pads import start_pads

    world = WorldConfig(vehicles=vehicles)
    camera = framing(world).camera()
    half_view_m = camera["distance"] * math.tan(math.radians(camera["fovy"]) / 2.0)
    centre = np.array(camera["targetOffset"][:2])
    reach = np.linalg.norm(start_pads(vehicles, world.spacing_m) - centre, axis=1) + 2.0 * world.radius_m
    assert reach.max() <= half_view_m, (reach.max(), half_view_m)


def test_the_compose_live_config_is_the_compose_config_with_the_live_view_on():
    from bus.config import load_config

    plain = load_config(ROOT / "deploy" / "compose-config.json", env={})
    live = load_config(ROOT / "deploy" / "compose-config-live.json", env={})
    assert live.view.live and live.view.live_host == "0.0.0.0" and live.view.live_port == 8765
    assert live.model_copy(update={"view": plain.view, "clock": plain.clock}) == plain
    assert (live.clock.tick_s, plain.clock.tick_s) == (0.5, 1.0)  # the live view is paced a tick at a time
    assert "./deploy/compose-config-live.json:/config/config.json" in (ROOT / "deploy" / "compose-live.yml").read_text()


def test_a_recording_that_cannot_be_written_leaves_the_run_going(tmp_path, caplog):
    from bus.config import ViewConfig
    from groundstation.recording_start import open_recording

    not_a_directory = tmp_path / "file"
    not_a_directory.write_text("")
    assert open_recording(not_a_directory, ViewConfig()) is None
    assert "run.mcap cannot be written" in caplog.text
    assert open_recording(tmp_path, ViewConfig(record=False)) is None


def test_rejected_input_shows_in_the_event_log_once_per_kind(tmp_path):
    """The ground station's own rejections and a vehicle's (from its status) reach /events as warnings."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    from bus import messages as m
    from bus.config import build_config
    from bus.memory import MemoryHub
    from bus.rejections import REASONS
    from bus.session import Envelope
    from groundstation.node import GroundStation

    config = build_config({"world": {"vehicles": 3}, "clock": {"duration_s": 10}})
    gs = GroundStation(MemoryHub().connect("groundstation"), config, tmp_path / "run")
    for _ in range(3):
        gs.handle(Envelope(gs.bus.keys.mavlink(2), b"garbage"))
    counts = tuple(4 if reason == "malformed" else 0 for reason in REASONS)
    gs.handle(
        Envelope(
            gs.bus.keys.status(1), m.encode(m.VehicleStatus(1, 500_000, 1, 0, 0.0, 0.0, 0, 0, 0, 0, rejected=counts))
        )
    )
    gs.finish("complete")
    with (tmp_path / "run" / "run.mcap").open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        logs = [decoded for _, _, _, decoded in reader.iter_decoded_messages(topics=["/events"])]
    rejected = [log.message for log in logs if "rejected input" in log.message]
    assert len(rejected) == 2, rejected  # the three garbage frames once; vehicle 1's count once
    assert "malformed" in rejected[0] and rejected[1].startswith("vehicle 1 rejected input (malformed): 4")


def test_a_viewer_that_never_reads_has_its_queue_overflow_counted_and_never_blocks_the_logger():
    """The live server with a 4-message queue and a viewer subscribed to /events that reads nothing:
    logging goes on (the oldest messages dropped) and each overflow the SDK reports is counted: the
    test logs until one is (a viewer that never reads must overflow a 4-message queue; if none is
    ever counted, pytest-timeout ends the test as failed)."""
    import socket
    import time

    from websockets.sync.client import connect

    from groundstation.recording import Recording

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    recording = Recording(None)
    recording.serve("127.0.0.1", port, backlog=4)
    try:
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # before connect: a small window
        sock.connect(("127.0.0.1", port))
        with connect(f"ws://127.0.0.1:{port}", sock=sock, subprotocols=["foxglove.sdk.v1"], close_timeout=1) as client:
            channel_id = None
            while channel_id is None:
                message = client.recv()
                if isinstance(message, str) and json.loads(message).get("op") == "advertise":
                    topics = {c["topic"]: c["id"] for c in json.loads(message)["channels"]}
                    channel_id = topics.get("/events")
            client.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channel_id}]}))
            text, logged, overflows = "x" * 65536, 0, 0
            # logging goes on until the SDK reports an overflow (from its own thread, once the server
            # has taken the subscription: that may come late on a loaded machine)
            while overflows == 0:
                for _ in range(16):
                    recording.message(1, text)
                logged += 16 * len(text)
                overflows += recording.overflows()
                time.sleep(0.001)
            assert overflows >= 1, f"{logged / 1e6:.0f} MB logged to a viewer that reads nothing, no overflow"
    finally:
        recording.close()


class _Messages:
    """A stand-in for ``foxglove.messages`` whose messages keep their fields readable (the SDK's are
    opaque): every name is a message type, called with its fields."""

    def __getattr__(self, name: str) -> "_Messages":
        return self

    def __call__(self, **fields) -> SimpleNamespace:
        return SimpleNamespace(**fields)


def test_a_uav_is_drawn_at_its_estimated_and_true_heights_and_a_level_vehicle_on_the_ground():
    from bus.mavlink_codec import StateEstimate
    from bus.odometry_content import NOT_ESTIMATED_VAR
    from groundstation.scene_entities import heights_m, vehicle_entity
    from groundstation.scoring import score_all

    def estimate(vid: int, height_var: float) -> StateEstimate:
        cov = np.diag([0.04, 0.04, height_var, 1e-4, 1e-4, 0.01])
        return StateEstimate(vid, 1_000_000, np.array([3.0, 4.0, -12.0]), 0.2, np.zeros(3), 0.0, cov, np.eye(6), 0)

    truth = np.array([3.1, 3.9, 0.2, 10.5])  # x, y, theta, height above the launch point
    uav, level = score_all([estimate(1, 0.5), estimate(2, NOT_ESTIMATED_VAR)], [truth, truth])
    assert heights_m(uav) == pytest.approx((12.0, 10.5)) and heights_m(level) == (0.0, 0.0)
    fm = _Messages()
    entity = vehicle_entity(fm, uav)
    estimated_arrow, true_arrow = entity.arrows
    assert estimated_arrow.pose.position.z == pytest.approx(12.0) and true_arrow.pose.position.z == pytest.approx(10.5)
    assert np.allclose([p.z for p in entity.lines[0].points], 12.0)
    assert {a.pose.position.z for a in vehicle_entity(fm, level).arrows} == {0.0}
    from groundstation.plot_records import metrics_record

    record = metrics_record(uav, (0.2, 9.3))  # the live view's plots: the UAV's height error and sigma
    assert record["err_alt_m"] == pytest.approx(1.5) and record["sigma_alt_m"] == pytest.approx(np.sqrt(0.5))
    assert "err_alt_m" not in metrics_record(level, (0.2, 9.3))


def test_maps_are_drawn_together_a_3d_one_as_ellipsoids_at_the_landmarks_heights_a_planar_one_as_rings():
    from bus.landmark_map import LandmarkMap
    from groundstation.scene_entities import landmark_update
    from groundstation.scene_primitives import ellipsoid

    cov3 = np.array([np.diag([0.2, 0.3, 4.0]), np.diag([1.0, 1.0, 1.0])])
    lmap = LandmarkMap(
        3, 2_000_000, np.array([[1.0, 2.0], [5.0, 6.0]]), cov3[:, :2, :2], np.array([-11.0, -13.5]), cov3
    )
    fm = _Messages()
    other = LandmarkMap(4, 2_000_000, lmap.xy_m + 50.0, lmap.covariance_m2)  # another vehicle's, on the ground
    entity, planar = landmark_update(fm, [lmap, other]).entities  # one update: a viewer seeking shows both
    assert (entity.id, planar.id) == ("landmarks-3", "landmarks-4")
    assert [(s.pose.position.x, s.pose.position.y, s.pose.position.z) for s in entity.spheres] == [
        (1.0, 2.0, -11.0),
        (5.0, 6.0, -13.5),
    ]
    size = entity.spheres[0].size
    assert np.allclose(sorted([size.x, size.y, size.z]), sorted(ellipsoid(cov3[0])[0]))
    assert np.allclose(sorted(ellipsoid(cov3[0])[0]), 6.0 * np.sqrt([0.2, 0.3, 4.0]))  # 3-sigma diameters
    assert not hasattr(planar, "spheres") and {p.z for p in planar.lines[0].points} == {0.0}


def test_the_recording_logs_every_vehicles_newest_map_together_at_most_once_a_second(tmp_path):
    """A viewer that seeks in run.mcap draws the newest /landmarks message: it holds every vehicle's map."""
    from mcap.reader import make_reader
    from mcap_protobuf.decoder import DecoderFactory

    from bus.landmark_map import LandmarkMap
    from groundstation.recording import Recording

    recording = Recording(tmp_path / "run.mcap")
    cov = np.array([np.eye(2) * 0.5])
    for stamp_us in (1_000_000, 1_300_000, 2_000_000, 2_400_000):  # a map of each vehicle a second, in turn
        for vid in (1, 2, 3):
            recording.landmarks(LandmarkMap(vid, stamp_us + 1000 * vid, np.array([[vid * 10.0, 0.0]]), cov))
    recording.close()
    with (tmp_path / "run.mcap").open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        updates = [(m.log_time, d) for _, c, m, d in reader.iter_decoded_messages() if c.topic == "/landmarks"]
    assert [t // 1000 for t, _ in updates] == [1_001_000, 2_001_000, 2_403_000]  # per second, then the last at the end
    assert [e.id for e in updates[-1][1].entities] == ["landmarks-1", "landmarks-2", "landmarks-3"]
    assert [e.id for e in updates[0][1].entities] == ["landmarks-1"]  # only vehicle 1 had sent one


def test_a_uav_swarms_layouts_plot_each_height_error_and_lichtblick_accepts_them():
    from bus.config import WorldConfig
    from bus.estimators import ESTIMATORS

    assert ESTIMATORS["ar-ekf-slam-3d"].estimates_height and not ESTIMATORS["ekf"].estimates_height
    layouts = swarm_layouts(WorldConfig(vehicles=3), heights=True)
    data = json.loads(layouts[LICHTBLICK_FILE])
    assert lichtblick_layout_errors(data) == []
    for text in layouts.values():
        assert all(f"/vehicle/{v}/metrics.err_alt_m" in text for v in (1, 2, 3)) and "height error [m]" in text
    assert "err_alt_m" not in json.dumps(swarm_layouts(WorldConfig(vehicles=3)))
