"""A calibration frozen in a file (sim.mrclam_calibration_file): `swarm replay calibrate` writes what the
replay would have calibrated, a replay that reads it gets the same datasheet, a file fitted on another
data set lets the whole of this one be replayed, and a file that is not one is refused in one line."""

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from bus.errors import ConfigError
from cli.main import app
from launch.replay_setup import ReplayChoice, replay_config
from sim.mrclam_calibration_file import read_calibration

EXCERPT = Path(__file__).resolve().parents[2] / "data" / "MRCLAM_Dataset6_first240s.tar.xz"


@pytest.fixture(scope="module")
def frozen(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("calibration") / "set6-0-120.json"
    result = CliRunner().invoke(
        app, ["replay", "calibrate", str(EXCERPT), "--interval", "0,120", "--out", str(path)], env={"COLUMNS": "300"}
    )
    assert result.exit_code == 0, result.output
    assert "fitted on MRCLAM_Dataset6_first240s [0, 120] s" in result.output
    return path


def test_a_replay_reading_the_file_gets_the_datasheet_it_would_have_calibrated(frozen):
    calibrated = replay_config(ReplayChoice(str(EXCERPT), duration_s=60.0), name="t")
    read = replay_config(ReplayChoice(str(EXCERPT), duration_s=60.0, calibration_file=str(frozen)), name="t")
    assert read.sensors == calibrated.sensors
    assert read.replay.model_dump(exclude={"calibration_file"}) == calibrated.replay.model_dump(
        exclude={"calibration_file"}
    )
    assert read.replay.calibration_file == str(frozen) and not read.replay.calibrated_elsewhere


def test_a_file_fitted_on_this_data_set_keeps_its_interval_out_of_the_window(frozen):
    with pytest.raises((ConfigError, ValueError), match="overlaps the calibration interval"):
        replay_config(ReplayChoice(str(EXCERPT), start_s=60.0, calibration_file=str(frozen)), name="t")


def test_a_file_fitted_on_another_data_set_lets_the_whole_of_this_one_be_replayed(frozen, tmp_path):
    other = json.loads(frozen.read_text())
    other["recorded_at_s"] += 86_400.0  # another recording
    other["dataset"] = "MRCLAM_Dataset7"
    path = tmp_path / "set7.json"
    path.write_text(json.dumps(other))
    config = replay_config(ReplayChoice(str(EXCERPT), duration_s=60.0, calibration_file=str(path)), name="t")
    assert config.replay.start_s == 0.0 and config.replay.calibrated_elsewhere


def test_a_robot_the_file_has_no_camera_for_is_named(frozen, tmp_path):
    partial = json.loads(frozen.read_text())
    del partial["sighting_sigmas"]["4"]
    path = tmp_path / "partial.json"
    path.write_text(json.dumps(partial))
    with pytest.raises(ConfigError, match="the calibration has no camera of robot 4"):
        replay_config(ReplayChoice(str(EXCERPT), duration_s=60.0, calibration_file=str(path)), name="t")


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda d: d.pop("sensors"), "sensors: Field required"),
        (lambda d: d.update(extra=1), "extra: Extra inputs are not permitted"),
        (lambda d: d["sensors"].update(bearing_sigma_rad=-1.0), "sensors.bearing_sigma_rad"),
        (lambda d: d.update(format="something else"), "format"),
        (lambda d: d.update(odom_lag_s="slow"), "odom_lag_s"),
    ],
)
def test_a_file_that_is_not_a_calibration_is_refused_in_one_line(frozen, tmp_path, change, message):
    broken = json.loads(frozen.read_text())
    change(broken)
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(broken))
    with pytest.raises(ConfigError, match=message) as caught:
        read_calibration(path)
    assert str(path) in str(caught.value) and "\n" not in str(caught.value)


def test_unreadable_and_missing_files_are_refused_in_one_line(tmp_path):
    (tmp_path / "binary.json").write_bytes(b"\xff\xfe\x00garbage")
    for path in (tmp_path / "missing.json", tmp_path / "binary.json", tmp_path):
        with pytest.raises(ConfigError, match="calibration file"):
            read_calibration(path)


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=10),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner, max_size=6),
    max_leaves=20,
)


@settings(max_examples=150, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    st.dictionaries(st.sampled_from(["format", "version", "sensors", "robots", "x", "sighting_sigmas"]), json_values)
)
def test_any_json_is_a_calibration_or_one_clear_error(tmp_path, document):
    path = tmp_path / "fuzz.json"
    path.write_text(json.dumps(document))
    try:
        read_calibration(path)
    except ConfigError as exc:
        assert str(exc).startswith(f"calibration file {path}: ")


@pytest.mark.parametrize(
    "args, message",
    [
        (["--interval", "5"], "--interval must be START,END"),
        (["--interval", "9,3"], "--interval must be START,END"),
        (["--robots", "1,9"], "--robots must be distinct robots 1-5"),
        (["--interval", "0,1"], "too little to calibrate on"),
    ],
)
def test_bad_calibrate_input_is_one_clear_line(tmp_path, args, message):
    result = CliRunner().invoke(
        app, ["replay", "calibrate", str(EXCERPT), "--out", str(tmp_path / "c.json"), *args], env={"COLUMNS": "300"}
    )
    assert result.exit_code == 1 and message in result.output and "Traceback" not in result.output, result.output
