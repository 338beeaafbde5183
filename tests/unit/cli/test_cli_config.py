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


def test_swarm_fault_add_knows_every_fault_kind_but_the_supervisor_s():
    """The kinds and their flags come from the registry (bus.faults): every kind is addable but
    ``kill`` (`swarm fault kill`), and every field a kind declares a flag for is an option of `add`."""
    from bus.faults import BY_KIND
    from cli.fault_commands import ADD_FLAGS
    from cli.fault_flags import addable_kinds

    assert set(addable_kinds()) == set(BY_KIND) - {"kill"}
    result = CliRunner().invoke(app, ["fault", "add", "--help"], env={"COLUMNS": "200"})
    for name in addable_kinds():
        for field, info in BY_KIND[name].model_fields.items():
            extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
            if "flag" in extra:
                assert field in ADD_FLAGS and extra["flag"] in result.output, (name, field)


def test_a_chaos_timeline_with_kill_faults_gets_the_short_tick_unless_one_was_given():
    from bus.config import build_config
    from cli.main import with_chaos

    plain = build_config({})
    assert plain.clock.tick_s == 1.0
    chaotic = with_chaos(plain, 7)
    assert any(f.kind == "kill" for f in chaotic.faults) and chaotic.clock.tick_s == 0.5
    assert with_chaos(build_config({"clock": {"tick_s": 0.1}}), 7, tick_given=True).clock.tick_s == 0.1


def test_restart_on_failure_shortens_only_lockstep_ticks():
    """The supervisor's restart policy may shorten lockstep's tick (a restarted ground station loses
    less); it leaves realtime's alone, whose 0.02 s tick hands every vehicle its samples in time."""
    from bus.config import build_config
    from cli.main import with_restart_tick

    assert with_restart_tick(build_config({})).clock.tick_s == 0.5
    assert with_restart_tick(build_config({"clock": {"tick_s": 0.2}})).clock.tick_s == 0.2
    realtime = build_config({"clock": {"mode": "realtime"}})
    assert with_restart_tick(realtime).clock.tick_s == realtime.clock.tick_s == 0.02


def test_swarm_up_with_restart_on_failure_keeps_the_realtime_tick(tmp_path, monkeypatch):
    """What `swarm up` hands the launcher: realtime's tick whatever the restart policy, lockstep's short."""
    import launch.launcher

    seen = {}

    def fake_launch(config, out, **kwargs):
        seen[(config.clock.mode, kwargs["restart"])] = config.clock.tick_s
        return tmp_path, [], []

    monkeypatch.setattr(launch.launcher, "launch", fake_launch)
    for mode in ("realtime", "lockstep"):
        for restart in ("no", "on-failure"):
            CliRunner().invoke(app, ["up", "--mode", mode, "--restart", restart, "--out", str(tmp_path), "--quiet"])
    assert seen == {
        ("realtime", "no"): 0.02,
        ("realtime", "on-failure"): 0.02,
        ("lockstep", "no"): 1.0,
        ("lockstep", "on-failure"): 0.5,
    }
