"""A replay's calibration is kept under a key of everything it depends on: the same data, the same
question (robots, interval, seed: launch.replay_setup.calibration_inputs) and the same code read it
back (no calibration run), anything else calibrates again; a kept file that does not read back, or
a folder that cannot be written, costs a calibration and nothing else."""

import dataclasses
import fcntl
import threading
from pathlib import Path

import numpy as np
import pytest

from launch.calibration_cache import cache_folder, calibration_key, remembered
from launch.replay_setup import ReplayChoice, calibration_inputs
from sim.mrclam_calibration_file import read_calibration, write_calibration
from tests.synthetic_mrclam import synthetic

FROZEN = Path(__file__).resolve().parents[3] / "calibrations" / "mrclam-set6-first-half.json"
CHOICE = ReplayChoice(dataset="data/set.tar.xz", robots=(1, 2), calibration_s=(0.0, 20.0))
ASKED = repr(calibration_inputs(CHOICE))


class Calibrations:
    """A stand-in calibration: the repository's frozen file, counted each time it is asked for."""

    def __init__(self) -> None:
        self.runs = 0
        self.result = read_calibration(FROZEN)

    def __call__(self):
        self.runs += 1
        return self.result


@pytest.fixture
def data():
    return synthetic(np.random.default_rng(4), robots=2, duration_s=30.0)


def test_the_second_replay_of_the_same_data_reads_the_calibration_back(tmp_path, data):
    calibrate = Calibrations()
    first = remembered(data, ASKED, calibrate, tmp_path)
    again = remembered(data, ASKED, calibrate, tmp_path)
    assert calibrate.runs == 1 and first == again == calibrate.result
    assert len(list(tmp_path.glob("*.json"))) == 1 and not list(tmp_path.glob("*.tmp"))


def test_other_robots_interval_seed_name_or_data_calibrate_again(tmp_path, data):
    calibrate = Calibrations()
    remembered(data, ASKED, calibrate, tmp_path)
    moved = dataclasses.replace(data, start_s=data.start_s + 1.0)
    robot = data.robots[1]
    nudged = robot.odometry.copy()
    nudged[5, 1] += 1e-9  # one odometry reading, in its last bits
    other_log = dataclasses.replace(data, robots={**data.robots, 1: dataclasses.replace(robot, odometry=nudged)})
    for other in (
        dataclasses.replace(CHOICE, robots=(1,)),
        dataclasses.replace(CHOICE, calibration_s=(0.0, 10.0)),
        dataclasses.replace(CHOICE, seed=1),
        dataclasses.replace(CHOICE, dataset="other.tar.xz"),
    ):
        remembered(data, repr(calibration_inputs(other)), calibrate, tmp_path)
    for changed in (moved, other_log):
        remembered(changed, ASKED, calibrate, tmp_path)
    assert calibrate.runs == 7 and len(list(tmp_path.glob("*.json"))) == 7


def test_a_kept_file_that_does_not_read_back_is_calibrated_again_and_replaced(tmp_path, data, caplog):
    calibrate = Calibrations()
    remembered(data, ASKED, calibrate, tmp_path)
    (kept,) = tmp_path.glob("*.json")
    kept.write_text('{"format": "swarmloc/mrclam-calibration", "vers')  # cut short
    assert remembered(data, ASKED, calibrate, tmp_path) == calibrate.result
    assert calibrate.runs == 2 and "calibrating again" in caplog.text
    assert read_calibration(kept) == calibrate.result


def test_a_folder_that_cannot_be_written_still_gives_the_calibration(tmp_path, data, caplog):
    blocked = tmp_path / "file"
    blocked.write_text("a file where the folder would be")
    calibrate = Calibrations()
    for _ in range(2):
        assert remembered(data, ASKED, calibrate, blocked / "calibrations") == calibrate.result
    assert calibrate.runs == 2 and "not kept" in caplog.text


def test_off_calibrates_every_time(data):
    calibrate = Calibrations()
    for _ in range(2):
        remembered(data, ASKED, calibrate, cache_folder({"SWARMLOC_CACHE": "off"}))
    assert calibrate.runs == 2


def test_the_folder_follows_the_environment(tmp_path):
    assert cache_folder({"SWARMLOC_CACHE": str(tmp_path)}) == tmp_path / "calibrations"
    assert cache_folder({"XDG_CACHE_HOME": str(tmp_path)}) == tmp_path / "swarmloc" / "calibrations"
    assert cache_folder({}) == Path.home() / ".cache" / "swarmloc" / "calibrations"
    assert cache_folder({"SWARMLOC_CACHE": "OFF"}) is None


def test_what_the_calibration_does_not_read_shares_its_key(data):
    """The estimator, its variant, the window and the data set's folder do not change a calibration
    (its held-out replays are known-map alone, inside the interval): one key for all of them."""
    copy = dataclasses.replace(data, robots={r: dataclasses.replace(log) for r, log in data.robots.items()})
    variant = dataclasses.replace(
        CHOICE,
        dataset="/elsewhere/set.tar.xz",
        estimator="slam",
        cooperative=True,
        start_s=130.0,
        duration_s=60.0,
        withhold_landmarks=(2,),
    )
    assert calibration_key(data, ASKED) == calibration_key(copy, repr(calibration_inputs(variant)))


def test_a_replay_that_starts_while_another_calibrates_waits_and_reads_what_it_kept(tmp_path, data):
    """The lock of the key held (as by a campaign's first replay, calibrating): the next replay
    waits instead of calibrating too, and takes the calibration the first one keeps."""
    calibrate = Calibrations()
    key = calibration_key(data, ASKED)
    got = []
    with (tmp_path / f"{key}.lock").open("a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        waiting = threading.Thread(target=lambda: got.append(remembered(data, ASKED, calibrate, tmp_path)))
        waiting.start()
        waiting.join(timeout=0.5)
        assert waiting.is_alive()  # it cannot go on while the lock is held
        write_calibration(tmp_path / f"{key}.json", calibrate.result)  # what the first one keeps
    waiting.join(timeout=30)
    assert got == [calibrate.result] and calibrate.runs == 0
