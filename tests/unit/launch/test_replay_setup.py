"""`swarm replay mrclam`: bad input is one line naming what is wrong; the config it builds gives the
vehicles the calibrated datasheet and the map, never the data set's truth."""

from pathlib import Path

import pytest
from typer.testing import CliRunner

from cli.main import app
from launch.replay_setup import ReplayChoice, replay_config

EXCERPT = Path(__file__).resolve().parents[2] / "data" / "MRCLAM_Dataset6_first240s.tar.xz"


@pytest.mark.parametrize(
    "args, message",
    [
        (["/nonexistent"], "neither a data set directory nor"),
        ([str(EXCERPT), "--robots", "1,7"], "robots must be distinct robots 1-5"),
        ([str(EXCERPT), "--robots", "1,2", "--withhold-landmarks", "4"], "names robots not replayed"),
        ([str(EXCERPT), "--estimator", "magic"], "unknown estimator 'magic'"),
        ([str(EXCERPT), "--calibrate", "0"], "--calibrate must be START,END"),
        ([str(EXCERPT), "--start", "500"], "after the data set's end"),
        ([str(EXCERPT), "--start", "60", "--duration", "30"], "overlaps the calibration interval"),
    ],
)
def test_bad_input_is_one_clear_line(tmp_path, args, message):
    result = CliRunner().invoke(app, ["replay", "mrclam", *args, "--out", str(tmp_path)])
    assert result.exit_code == 1 and message in result.output and "Traceback" not in result.output, result.output


def test_the_vehicles_get_the_calibrated_datasheet_and_the_map_but_no_truth():
    config = replay_config(ReplayChoice(str(EXCERPT), duration_s=60.0), name="t")
    assert config.replay.start_s == 120.0 and config.clock.duration_s == 60.0 and config.world.vehicles == 5
    assert 0.1 <= config.replay.odom_lag_s <= 0.3 and len(config.replay.sighting_sigmas) == 5
    vehicle = config.for_vehicle()
    assert len(vehicle.vehicle.landmarks) == 15 and vehicle.vehicle.estimator == "known-map"
    assert vehicle.sensors.odom_yaw_rate_sigma_radps == config.sensors.odom_yaw_rate_sigma_radps
    assert vehicle.sensors.odom_turn_sigma_rad == config.sensors.odom_turn_sigma_rad > 0  # robots that slip in turns
    assert "replay" not in vehicle.model_dump() and "dataset" not in vehicle.model_dump_json()


def test_odometry_errors_of_replayed_robots_are_refused_for_the_simulated_world():
    from bus.config import build_config
    from bus.errors import ConfigError

    with pytest.raises((ConfigError, ValueError), match="the simulated world makes no such error"):
        build_config({"sensors": {"odom_turn_sigma_rad": 0.1}})
