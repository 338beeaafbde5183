"""Config validation, key expressions (built and parsed, totally), and role enforcement in the bus layer."""

import json
import queue

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus.config import BusConfig, SwarmConfig, build_config
from bus.errors import AccessDenied, ConfigError
from bus.keys import KeySpace, ParsedKey, parse_vehicle_id
from bus.memory import MemoryHub
from bus.session import ZenohBus


def test_bad_values_name_the_field():
    with pytest.raises(ConfigError, match="world.vehicles"):
        build_config({"world": {"vehicles": 0}})
    with pytest.raises(ConfigError, match="clock.duration_s"):
        build_config({"clock": {"duration_s": -1}})
    with pytest.raises(ConfigError, match="clock.mode"):
        build_config({"clock": {"mode": "turbo"}})
    with pytest.raises(ConfigError, match="multiple of the IMU period"):
        build_config({"sensors": {"gnss_rate_hz": 3.0}})


def test_environment_overrides_bus_endpoints():
    conf = BusConfig().with_env(
        {
            "SWARMLOC_ZENOH_CONNECT": "tcp/10.0.0.1:7447, tcp/10.0.0.2:7447",
            "SWARMLOC_ZENOH_MODE": "peer",
            "SWARMLOC_PREFIX": "fleet/a",
        }
    )
    assert conf.connect == ("tcp/10.0.0.1:7447", "tcp/10.0.0.2:7447")
    assert (conf.mode, conf.prefix) == ("peer", "fleet/a")
    with pytest.raises(ConfigError, match="mode"):
        BusConfig().with_env({"SWARMLOC_ZENOH_MODE": "satellite"})


def test_defaults_round_trip_through_json(tmp_path):
    from bus.config import load_config

    SwarmConfig().dump(tmp_path / "c.json")
    assert load_config(tmp_path / "c.json") == SwarmConfig()


@pytest.mark.parametrize(
    "expr, is_truth",
    [
        ("swarm/truth", True),
        ("swarm/*", True),
        ("swarm/**", True),
        ("**", True),
        ("swarm/v/3/feed", False),
        ("swarm/v/*/mavlink", False),
        ("swarm/ctl/clock", False),
        ("swarm/v/**", False),
        ("not a key//", False),
    ],
)
def test_truth_detection_covers_wildcards(expr, is_truth):
    assert KeySpace("swarm").is_truth(expr) is is_truth


@pytest.mark.parametrize(
    "text, expected",
    [
        ("1", 1),
        ("250", 250),
        ("42", 42),
        ("0", None),
        ("251", None),
        ("007", None),
        ("²", None),
        ("-3", None),
        ("+3", None),
        (" 3", None),
        ("3 ", None),
        ("３", None),
        ("", None),
        ("x", None),
        ("1e2", None),
        ("99999999999999", None),
    ],
)
def test_vehicle_ids_are_plain_ascii_decimals_in_range(text, expected):
    assert parse_vehicle_id(text) == expected


def test_keys_parse_to_what_they_name():
    keys = KeySpace("swarm")
    assert keys.parse(keys.mavlink(7)) == ParsedKey("vehicle", 7, "mavlink")
    assert keys.parse(keys.feed(250)) == ParsedKey("vehicle", 250, "feed")
    assert keys.parse(keys.v2v(4)) == ParsedKey("vehicle", 4, "v2v")
    assert keys.parse(keys.v2v_to(4, 9)) == ParsedKey("vehicle", 4, "v2v", recipient=9)
    assert keys.parse(keys.ack(3)) == ParsedKey("ack", 3)
    assert keys.parse(keys.ack("gs")) == ParsedKey("ack", ident="gs")
    assert keys.parse(keys.alive("vehicle", 4)) == ParsedKey("alive", 4, role="vehicle", ident="4")
    assert keys.parse(keys.truth()).kind == "truth" and keys.parse(keys.clock()).kind == "clock"
    assert keys.parse(keys.pace()).kind == "pace"
    for bad in (
        "swarm/v/x/v2v",
        "swarm/v/²/mavlink",
        "swarm/v/3/sensor/imu",
        "swarm/v/3/mavlink/extra",
        "swarm/v/3/v2v/0",
        "swarm/v/3/v2v/x",
        "swarm/v/3/v2v/4/5",
        "swarm/v/3/feed/4",
        "swarm/alive/vehicle/²",
        "swarm/alive/pilot/1",
        "other/v/1/mavlink",
        "swarm",
        "swarm/ctl/ack/0",
    ):
        assert keys.parse(bad) is None, bad
        assert keys.vehicle_of(bad) is None


@given(st.text(max_size=40))
def test_any_key_parses_or_gives_none(tail):
    keys = KeySpace("swarm")
    for key in (
        tail,
        f"swarm/{tail}",
        f"swarm/v/{tail}/mavlink",
        f"swarm/alive/vehicle/{tail}",
        f"swarm/ctl/ack/{tail}",
        f"swarm/v/3/v2v/{tail}",
        f"swarm/v/{tail}/v2v/3",
    ):
        parsed = keys.parse(key)
        assert parsed is None or isinstance(parsed, ParsedKey)
        assert parsed is None or parsed.vehicle_id is None or 1 <= parsed.vehicle_id <= 250
        assert parsed is None or parsed.recipient is None or 1 <= parsed.recipient <= 250


def test_memory_bus_refuses_truth_to_vehicles_and_delivers_to_others():
    hub = MemoryHub()
    inbox = queue.SimpleQueue()
    with pytest.raises(AccessDenied):
        hub.connect("vehicle").subscribe("swarm/truth", inbox)
    hub.connect("groundstation").subscribe("swarm/truth", inbox)
    hub.connect("world").publisher("swarm/truth").put(b"x")
    assert inbox.get_nowait().payload == b"x"


def test_subscriptions_hand_on_oversized_payloads_as_markers_only():
    from bus.mailbox import Oversized

    hub = MemoryHub()
    inbox = queue.SimpleQueue()
    hub.connect("groundstation").subscribe("swarm/v/*/mavlink", inbox, max_bytes=10)
    hub.connect("vehicle").publisher("swarm/v/1/mavlink").put(b"x" * 11)
    assert inbox.get_nowait() == Oversized("swarm/v/1/mavlink", 11)


def test_a_router_opens_without_scouting_for_peers_and_clients_keep_the_default():
    from bus.session import zenoh_config

    assert json.loads(zenoh_config(BusConfig(mode="router")).get_json("scouting/delay")) == 0
    assert json.loads(zenoh_config(BusConfig(mode="client")).get_json("scouting/delay")) is None


def test_zenoh_bus_refuses_truth_to_vehicles():
    with ZenohBus(BusConfig(mode="peer", connect=(), listen=()), role="vehicle") as bus:
        with pytest.raises(AccessDenied, match="truth"):
            bus.subscribe(bus.keys.truth(), queue.SimpleQueue())
        with pytest.raises(AccessDenied):
            bus.subscribe("swarm/**", queue.SimpleQueue())
        bus.subscribe(bus.keys.feed(1), queue.SimpleQueue())  # allowed


def test_the_compose_vehicle_config_is_the_vehicle_part_of_the_compose_config():
    """deploy/compose-vehicle.json is what vehicle containers get: it must stay in step with the
    swarm's config and carry nothing that determines truth."""
    import json
    from pathlib import Path

    from bus.config import load_config, load_vehicle_config

    deploy = Path(__file__).resolve().parents[3] / "deploy"
    swarm = load_config(deploy / "compose-config.json", env={})
    assert load_vehicle_config(deploy / "compose-vehicle.json", env={}) == swarm.for_vehicle()
    assert "seed" not in json.loads((deploy / "compose-vehicle.json").read_text()) and "world" not in json.loads(
        (deploy / "compose-vehicle.json").read_text()
    )


def test_vehicle_configs_take_the_swarm_size_from_the_environment(tmp_path):
    from bus.config import load_vehicle_config

    SwarmConfig().for_vehicle().dump(tmp_path / "v.json")
    assert load_vehicle_config(tmp_path / "v.json", env={"SWARMLOC_VEHICLES": "8"}).vehicles == 8
    with pytest.raises(ConfigError, match="SWARMLOC_VEHICLES"):
        load_vehicle_config(tmp_path / "v.json", env={"SWARMLOC_VEHICLES": "eight"})
    (tmp_path / "bad.json").write_text("[1, 2]")
    with pytest.raises(ConfigError, match="object"):
        load_vehicle_config(tmp_path / "bad.json", env={})


def test_estimator_options_that_do_not_fit_together_are_refused():
    with pytest.raises(ConfigError, match="needs a camera"):
        build_config({"vehicle": {"estimator": "ekf-slam"}})
    with pytest.raises(ConfigError, match="cooperation.fusion"):
        build_config({"vehicle": {"cooperation": {"fusion": "fancy"}}})
    with pytest.raises(ConfigError, match="vehicle.cooperative_fusion is now vehicle.cooperation.fusion"):
        build_config({"vehicle": {"cooperative_fusion": "ci"}})  # a key of before the parts: where it went
    assert build_config({"vehicle": {"estimator": "ukf"}, "sensors": {"camera_rate_hz": 10}}).vehicle.estimator == "ukf"


@pytest.mark.parametrize(
    ("data", "tick_s"),
    [
        ({}, 1.0),
        ({"clock": {"mode": "realtime"}}, 0.02),
        ({"sensors": {"camera_rate_hz": 10}}, 0.5),  # a tick's batch of camera frames grows with the tick
        ({"view": {"live": True}}, 0.5),  # a live view is paced a tick at a time
        ({"faults": [{"kind": "kill", "vehicle": 2, "start_s": 10.3}]}, 0.5),  # a kill lands at a tick's end
        ({"faults": [{"kind": "jam-gnss", "center_m": [0, 0], "radius_m": 5}]}, 1.0),
        ({"clock": {"tick_s": 0.1}, "sensors": {"camera_rate_hz": 10}}, 0.1),  # a given tick is kept
        ({"world": {"vehicles": 250}}, 1.0),  # a 1 s truth batch: about 530 kB of the ground station's 1 MB
        ({"world": {"vehicles": 250}, "sensors": {"truth_rate_hz": 100}}, 0.5),  # 1 s would pass it
    ],
)
def test_the_lockstep_tick_is_one_second_unless_a_longer_tick_would_cost_something(data, tick_s):
    assert build_config(data).clock.tick_s == tick_s
    assert build_config({}).clock.tick_s == 1.0  # no configuration changes another's default


def test_a_truth_batch_larger_than_the_ground_station_takes_is_refused_in_one_line():
    with pytest.raises(ConfigError, match="truth batch .* lower sensors.truth_rate_hz or clock.tick_s"):
        build_config({"world": {"vehicles": 250}, "sensors": {"truth_rate_hz": 100}, "clock": {"tick_s": 1.0}})


def test_the_truth_batch_estimate_covers_what_the_world_sends():
    """The estimate the configuration checks against is at least the encoded size of a real tick."""
    import numpy as np

    from bus import feed
    from sim.world import World

    config = build_config({"world": {"vehicles": 60, "seed": 1}, "clock": {"duration_s": 2}})
    world = World(config)
    out = world.advance(round(config.clock.tick_s * 1e6))
    ids = world.vehicle_ids()
    rows = np.array(out.truth).reshape(len(out.truth_stamps), len(ids), feed.TRUTH_WIDTH)
    pairs = np.array([(o, t) for t, obs in out.listeners().items() for o in obs], np.int64).reshape(-1, 2)
    batch = feed.TruthBatch(1, out.truth_stamps[-1], np.array(out.truth_stamps), np.array(ids), rows, pairs)
    encoded = len(feed.encode_truth(batch))
    estimate = feed.truth_batch_bytes(config.sensors.truth_rate_hz, config.clock.tick_s, 60)
    assert encoded <= estimate <= 1.3 * encoded
