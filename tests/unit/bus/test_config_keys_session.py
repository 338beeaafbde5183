"""Config validation, key expressions, and role enforcement in the bus layer."""

import queue

import pytest

from bus.config import BusConfig, SwarmConfig, build_config
from bus.errors import AccessDenied, ConfigError
from bus.keys import KeySpace
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
    conf = BusConfig().with_env({"SWARMLOC_ZENOH_CONNECT": "tcp/10.0.0.1:7447, tcp/10.0.0.2:7447",
                                 "SWARMLOC_ZENOH_MODE": "peer", "SWARMLOC_PREFIX": "fleet/a"})
    assert conf.connect == ("tcp/10.0.0.1:7447", "tcp/10.0.0.2:7447")
    assert (conf.mode, conf.prefix) == ("peer", "fleet/a")
    with pytest.raises(ConfigError, match="mode"):
        BusConfig().with_env({"SWARMLOC_ZENOH_MODE": "satellite"})


def test_defaults_round_trip_through_json(tmp_path):
    from bus.config import load_config
    SwarmConfig().dump(tmp_path / "c.json")
    assert load_config(tmp_path / "c.json") == SwarmConfig()


@pytest.mark.parametrize("expr, is_truth", [
    ("swarm/v/3/truth", True), ("swarm/v/*/truth", True), ("swarm/**", True), ("swarm/v/3/*", True),
    ("**", True), ("swarm/v/3/sensor/*", False), ("swarm/v/3/mavlink", False), ("swarm/ctl/clock", False),
])
def test_truth_detection_covers_wildcards(expr, is_truth):
    assert KeySpace("swarm").is_truth(expr) is is_truth


def test_memory_bus_refuses_truth_to_vehicles_and_delivers_to_others():
    hub = MemoryHub()
    inbox = queue.SimpleQueue()
    with pytest.raises(AccessDenied):
        hub.connect("vehicle").subscribe("swarm/v/*/truth", inbox)
    hub.connect("groundstation").subscribe("swarm/v/*/truth", inbox)
    hub.connect("world").publisher("swarm/v/1/truth").put(b"x")
    assert inbox.get_nowait().payload == b"x"


def test_zenoh_bus_refuses_truth_to_vehicles():
    with ZenohBus(BusConfig(mode="peer", connect=(), listen=()), role="vehicle") as bus:
        with pytest.raises(AccessDenied, match="truth"):
            bus.subscribe(bus.keys.truth(1), queue.SimpleQueue())
        with pytest.raises(AccessDenied):
            bus.subscribe("swarm/**", queue.SimpleQueue())
        bus.subscribe(bus.keys.sensors(1), queue.SimpleQueue())  # allowed
