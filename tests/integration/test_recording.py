"""run.mcap and the live view through real processes: every run directory gets run.mcap, read back
here with the mcap library against the run's metrics.csv; `swarm up --live` serves the Foxglove
WebSocket protocol to a real client while a lockstep run goes on, and a run stopped by Ctrl-C leaves
a finished, readable recording."""

import csv
import json
import os
import signal
import socket
import subprocess
import time
from collections import defaultdict

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from tests.integration.conftest import ESTIMATES_PER_S, run_swarm, swarm_command
from tests.viewer_rules import FREQUENCY_LIMIT_HZ, json_schema_errors, lichtblick_layout_errors

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    out = tmp_path_factory.mktemp("mcap")
    result = run_swarm(out, "--vehicles", "3", "--duration", "10", "--mode", "lockstep", "--name", "rec", "--seed", "2")
    assert result.returncode == 0, result.stdout + result.stderr
    return out / "rec"


def _metrics(run) -> list[dict]:
    with (run / "metrics.csv").open() as handle:
        return list(csv.DictReader(handle))


class _JsonDecoders:
    def decoder_for(self, encoding, schema):
        return json.loads if encoding == "json" else None


def _decoded(path):
    with path.open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory(), _JsonDecoders()])
        return [(c.topic, m.log_time, decoded) for _, c, m, decoded in reader.iter_decoded_messages()]


def test_run_mcap_holds_every_channel_with_one_estimate_per_scored_sample(recorded):
    with (recorded / "run.mcap").open("rb") as handle:
        summary = make_reader(handle).get_summary()
    schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    for vid in (1, 2, 3):
        assert schemas[f"/vehicle/{vid}/estimate"] == schemas[f"/vehicle/{vid}/truth"] == "foxglove.PoseInFrame"
    assert schemas["/scene"] == "foxglove.SceneUpdate" and schemas["/events"] == "foxglove.Log"
    assert all(schemas[f"/vehicle/{v}/metrics"] == "swarmloc.Metrics" for v in (1, 2, 3))
    assert schemas["/swarm"] == "swarmloc.SwarmError"
    assert schemas["/ranging"] == "foxglove.SceneUpdate" and schemas["/trails"] == "foxglove.SceneUpdate"
    assert all(schemas[f"/vehicle/{v}/health"] == "swarmloc.GnssHealth" for v in (1, 2, 3))
    assert all(schemas[f"/vehicle/{v}/loop"] == "swarmloc.LoopStatus" for v in (1, 2, 3))
    counts = {c.topic: summary.statistics.channel_message_counts[c.id] for c in summary.channels.values()}
    rows = _metrics(recorded)
    per_vehicle = defaultdict(int)
    for row in rows:
        per_vehicle[int(row["vehicle"])] += 1
    for vid, n in per_vehicle.items():
        assert counts[f"/vehicle/{vid}/estimate"] == counts[f"/vehicle/{vid}/truth"] == n
        assert counts[f"/vehicle/{vid}/metrics"] == n
    events = (recorded / "events.jsonl").read_text().splitlines()
    assert counts["/events"] == len(events)


def test_times_are_sim_time_and_monotonic_and_the_poses_give_the_scored_error(recorded):
    messages = _decoded(recorded / "run.mcap")
    last = {}
    for topic, log_time, _ in messages:
        assert log_time >= last.get(topic, 0), topic
        last[topic] = log_time
        assert log_time <= 10_000_000_000  # nanoseconds of sim time: the run lasted 10 s
    poses = {
        (topic, t): d.pose.position for topic, t, d in messages if topic in ("/vehicle/2/estimate", "/vehicle/2/truth")
    }
    row = next(r for r in _metrics(recorded) if r["vehicle"] == "2" and float(r["t_s"]) == 5.0)
    t = 5_000_000_000
    est, truth = poses[("/vehicle/2/estimate", t)], poses[("/vehicle/2/truth", t)]
    error = np.hypot(est.x - truth.x, est.y - truth.y)
    assert error == pytest.approx(float(row["err_pos_m"]), abs=2e-6)
    scene = [d for topic, _, d in messages if topic == "/scene"]
    assert {e.id for update in scene for e in update.entities} == {"vehicle-1", "vehicle-2", "vehicle-3"}
    assert all(len(e.lines[0].points) == 36 for update in scene for e in update.entities)


def test_every_json_schema_is_one_the_viewers_parse_and_no_topic_passes_their_frequency_warning(recorded):
    """Lichtblick refuses a channel whose JSON schema it cannot parse (a type array once dropped all
    the plots' data) and warns above 60 messages a second on a topic; the run's layouts are what its
    import accepts."""
    with (recorded / "run.mcap").open("rb") as handle:
        summary = make_reader(handle).get_summary()
    stats = summary.statistics
    duration_s = (stats.message_end_time - stats.message_start_time) * 1e-9
    checked = 0
    for channel in summary.channels.values():
        schema = summary.schemas[channel.schema_id]
        if schema.encoding == "jsonschema":
            assert json_schema_errors(json.loads(schema.data)) == [], channel.topic
            checked += 1
        if schema.name != "foxglove.Log":  # the viewers exempt log topics
            rate = stats.channel_message_counts[channel.id] / duration_s
            assert rate <= FREQUENCY_LIMIT_HZ, (channel.topic, rate)
    assert checked >= 4  # metrics, swarm, health, loop
    assert lichtblick_layout_errors(json.loads((recorded / "layout-lichtblick.json").read_text())) == []
    assert json.loads((recorded / "layout-foxglove.json").read_text())["version"] == 1
    no_nees = [d for t, _, d in _decoded(recorded / "run.mcap") if t.endswith("/metrics") and "nees" not in d]
    assert all(
        v is not None for t, _, d in _decoded(recorded / "run.mcap") if t.endswith("/metrics") for v in d.values()
    )
    assert len(no_nees) < 10  # a NEES is left out only where it is not finite


def test_ranging_lines_join_true_positions_and_status_channels_follow_every_vehicle(recorded):
    messages = _decoded(recorded / "run.mcap")
    truth = {(topic, t): (d.pose.position.x, d.pose.position.y) for topic, t, d in messages if topic.endswith("/truth")}
    true_points = {xy for xy in truth.values()}
    lines = [e.lines[0].points for topic, _, d in messages if topic == "/ranging" for e in d.entities]
    drawn = [p for points in lines for p in points]
    assert len(drawn) > 0 and all(len(points) % 2 == 0 for points in lines)
    assert all((p.x, p.y) in true_points for p in drawn)  # the world's ranging pairs, at the true positions
    trails = {e.id: e for topic, _, d in messages if topic == "/trails" for e in d.entities}  # the newest
    assert set(trails) == {"trail-1", "trail-2", "trail-3"}
    for entity in trails.values():
        true_trail, estimated_trail = (line.points for line in entity.lines)
        assert 2 <= len(true_trail) == len(estimated_trail) <= 31  # the last 30 s, a point a second
        assert all((p.x, p.y) in true_points for p in true_trail)
    rows = _metrics(recorded)
    swarm = {round(d["t_s"], 6): d for topic, _, d in messages if topic == "/swarm"}
    assert set(swarm) == {round(float(r["t_s"]), 6) for r in rows}
    at_5 = [float(r["err_pos_m"]) for r in rows if float(r["t_s"]) == 5.0]
    assert swarm[5.0]["rms_error_m"] == pytest.approx(np.sqrt(np.mean(np.square(at_5))), rel=1e-5)
    health = [d for topic, _, d in messages if topic.endswith("/health")]
    loops = [d for topic, _, d in messages if topic.endswith("/loop")]
    assert {d["vehicle"] for d in health} == {d["vehicle"] for d in loops} == {1, 2, 3}
    assert not any(d["gnss_glitch"] for d in health)  # a clean run
    assert max(d["cycles"] for d in loops if d["vehicle"] == 1) > 0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_live_client_sees_the_channels_and_every_vehicle_and_ctrl_c_leaves_a_finished_recording(tmp_path):
    from websockets.sync.client import connect

    port = _free_port()
    command = swarm_command(
        tmp_path, "--vehicles", "2", "--duration", "3600", "--mode", "lockstep", "--name", "live", "--live",
        "--live-port", str(port),
    )  # fmt: skip
    swarm = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=os.environ)
    try:
        deadline, client = time.monotonic() + 120, None
        while client is None:
            assert swarm.poll() is None, swarm.stdout.read()
            assert time.monotonic() < deadline, "the live view never answered"
            try:
                client = connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.sdk.v1", "foxglove.websocket.v1"])
            except OSError:
                time.sleep(0.2)
        with client:
            channels, seen, capabilities, clock = {}, set(), [], []
            while time.monotonic() < deadline and (seen != {b"vehicle-1", b"vehicle-2"} or not clock):
                frame = client.recv(timeout=30)
                if isinstance(frame, str):
                    message = json.loads(frame)
                    capabilities += message.get("capabilities", []) if message.get("op") == "serverInfo" else []
                    if message.get("op") == "advertise":
                        channels.update({c["topic"]: c["id"] for c in message["channels"]})
                        if "/scene" in channels and not seen:
                            request = {"op": "subscribe", "subscriptions": [{"id": 1, "channelId": channels["/scene"]}]}
                            client.send(json.dumps(request))
                elif frame[0] == 1:  # message data: opcode, subscription id, timestamp, payload
                    seen |= {v for v in (b"vehicle-1", b"vehicle-2") if v in frame[13:]}
                elif frame[0] == 2:  # time: opcode, nanoseconds
                    clock.append(int.from_bytes(frame[1:9], "little"))
            assert {"/scene", "/vehicle/1/metrics", "/events", "/vehicle/1/estimate"} <= set(channels)
            assert "time" in capabilities and clock and max(clock) < 3600e9  # the run's sim time, not wall time
            assert seen == {b"vehicle-1", b"vehicle-2"}
    finally:
        swarm.send_signal(signal.SIGINT)
        output = swarm.communicate(timeout=120)[0]
    with (tmp_path / "live" / "run.mcap").open("rb") as handle:
        summary = make_reader(handle).get_summary()  # the footer and index: the file was finished
    assert summary is not None and sum(summary.statistics.channel_message_counts.values()) > 0, output


def test_a_viewer_that_never_reads_loses_messages_counted_and_never_holds_the_run(tmp_path):
    """A viewer that subscribes to every channel and then reads nothing (its queue 4 messages here):
    the run ends normally with every sample scored and a finished run.mcap. Whether the queue
    overflows depends on how much the kernel buffers on loopback (a 3-vehicle minute is ~3 MB, the
    send buffer may grow to 4 MB), so the counting of overflows is checked in the unit test that
    logs many times the kernel's buffers (tests/unit/groundstation/test_recording.py)."""
    from websockets.sync.client import connect

    port = _free_port()
    scenario = tmp_path / "slow.toml"
    scenario.write_text(f"[view]\nlive = true\nlive_port = {port}\nlive_backlog = 4\n")
    command = swarm_command(tmp_path, str(scenario), "--vehicles", "3", "--duration", "60", "--mode", "lockstep",
                            "--name", "slow")  # fmt: skip
    swarm = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=os.environ)
    deadline, sock = time.monotonic() + 120, None
    while sock is None:
        assert swarm.poll() is None and time.monotonic() < deadline, "the live view never answered"
        try:
            sock = socket.create_connection(("127.0.0.1", port))
        except OSError:
            time.sleep(0.2)
    protocols = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
    with connect(f"ws://127.0.0.1:{port}", sock=sock, subprotocols=protocols) as client:
        channels: dict[str, int] = {}
        while "/vehicle/1/metrics" not in channels:
            message = client.recv(timeout=30)
            if isinstance(message, str) and json.loads(message).get("op") == "advertise":
                channels.update({c["topic"]: c["id"] for c in json.loads(message)["channels"]})
        subscriptions = [{"id": k, "channelId": cid} for k, cid in enumerate(channels.values())]
        client.send(json.dumps({"op": "subscribe", "subscriptions": subscriptions}))
        output = swarm.communicate(timeout=300)[0]  # the viewer reads nothing more
    assert swarm.returncode == 0, output
    summary = json.loads((tmp_path / "slow" / "summary.json").read_text())
    assert summary["swarm"]["samples"] == 3 * 601, summary["swarm"]  # every vehicle at 10 Hz, 0 to 60 s
    with (tmp_path / "slow" / "run.mcap").open("rb") as handle:
        assert make_reader(handle).get_summary() is not None  # the file was finished


def test_a_live_port_in_use_is_refused_before_anything_starts(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = run_swarm(tmp_path, "--vehicles", "1", "--duration", "2", "--live", "--live-port", str(port))
    assert result.returncode != 0
    assert f"cannot serve on 127.0.0.1:{port}" in result.stdout + result.stderr
    assert "Traceback" not in result.stdout + result.stderr
    assert not list(tmp_path.glob("*/metrics.csv"))  # no process started
    bad = run_swarm(tmp_path, "--vehicles", "1", "--duration", "2", "--live", "--live-host", "no.such.host.invalid")
    assert bad.returncode != 0 and "is not an address" in bad.stdout + bad.stderr


def test_the_recording_can_be_turned_off(tmp_path):
    result = run_swarm(
        tmp_path, "--vehicles", "1", "--duration", "2", "--mode", "lockstep", "--name", "n", "--no-record"
    )
    assert result.returncode == 0, result.stdout + result.stderr
    assert not (tmp_path / "n" / "run.mcap").exists() and (tmp_path / "n" / "metrics.csv").exists()


def test_fault_zones_are_drawn_while_active_and_deleted_when_they_end(tmp_path):
    scenario = tmp_path / "zones.toml"
    scenario.write_text(
        'name = "zones"\n[world]\nvehicles = 2\n[clock]\nduration_s = 6\n'
        '[[faults]]\nname = "jammer"\nkind = "jam-gnss"\ncenter_m = [0.0, 0.0]\nradius_m = 40.0\n'
        "start_s = 2.0\nfor_s = 2.0\n"
    )
    result = run_swarm(tmp_path, str(scenario), "--mode", "lockstep", "--name", "zones")
    assert result.returncode == 0, result.stdout + result.stderr
    zones = [(t, d) for topic, t, d in _decoded(tmp_path / "zones" / "run.mcap") if topic == "/zones"]
    drawn = [t for t, d in zones if any(e.id == "zone-jammer" for e in d.entities)]
    deleted = [t for t, d in zones if any(x.id == "zone-jammer" for x in d.deletions)]
    assert len(drawn) == 1 and 2e9 <= drawn[0] <= 2.5e9, zones
    assert len(deleted) == 1 and 4e9 <= deleted[0] <= 4.5e9, zones


def test_a_paced_live_view_runs_a_lockstep_swarm_to_its_end(tmp_path):
    """`--live-speed 2`: the ground station holds its tick acknowledgements to twice real time (the rule,
    with the wall clock injected: tests/unit/groundstation/test_live_pacing.py); held so, the real
    processes still finish the run, every estimate scored."""
    scenario = tmp_path / "paced.toml"
    scenario.write_text(f"[view]\nlive = true\nlive_port = {_free_port()}\n")
    result = run_swarm(
        tmp_path, str(scenario), "--vehicles", "2", "--duration", "6", "--mode", "lockstep", "--name", "paced",
        "--live-speed", "2",
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    summary = json.loads((tmp_path / "paced" / "summary.json").read_text())
    assert summary["status"] == "complete"
    assert json.loads((tmp_path / "paced" / "config.json").read_text())["view"]["live_speed"] == 2.0
    assert all(v["samples"] == 6 * ESTIMATES_PER_S + 1 for v in summary["vehicles"].values()), summary["vehicles"]
