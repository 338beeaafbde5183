"""`swarm config` writes a deployment's two configs: the vehicles' one holds nothing that determines
truth; bad input is a one-line error."""

import json

from typer.testing import CliRunner

from bus.config import load_config, load_vehicle_config
from cli.main import app


def test_config_writes_the_world_config_and_a_vehicle_config_without_truth(tmp_path):
    result = CliRunner().invoke(app, ["config", "--out", str(tmp_path), "--vehicles", "3", "--seed", "9"])
    assert result.exit_code == 0, result.output
    assert load_config(tmp_path / "config.json").world.seed == 9
    vehicle = json.loads((tmp_path / "vehicle.json").read_text())
    assert load_vehicle_config(tmp_path / "vehicle.json").vehicles == 3
    text = json.dumps(vehicle)  # fault_seed (link-fault decisions) is all a vehicle may know of seeds
    assert '"seed"' not in text and "trajector" not in text and "world" not in vehicle


def test_config_refuses_bad_input_in_one_line(tmp_path):
    result = CliRunner().invoke(app, ["config", "--out", str(tmp_path), "--vehicles", "300"])
    assert result.exit_code == 1 and "world.vehicles" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "config.json").exists()


def test_the_fault_commands_know_every_fault_kind_the_plan_has():
    from bus.faults import BEHAVIOUR_KINDS, LINK_KINDS, PHYSICAL_KINDS
    from cli.fault_commands import KINDS

    assert set(KINDS) == {*LINK_KINDS, *PHYSICAL_KINDS, *BEHAVIOUR_KINDS}


def test_a_chaos_timeline_with_kill_faults_gets_the_short_tick_unless_one_was_given():
    from bus.config import build_config
    from cli.main import with_chaos

    plain = build_config({})
    assert plain.clock.tick_s == 1.0
    chaotic = with_chaos(plain, 7)
    assert any(f.kind == "kill" for f in chaotic.faults) and chaotic.clock.tick_s == 0.5
    assert with_chaos(build_config({"clock": {"tick_s": 0.1}}), 7, tick_given=True).clock.tick_s == 0.1
