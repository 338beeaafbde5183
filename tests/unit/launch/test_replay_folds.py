"""Two-fold cross-validation of a replay (launch.replay_setup.fold_of): each fold replays the half
the other was calibrated on, from the first second every replayed robot has ground truth."""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from bus.errors import ConfigError
from launch.replay_setup import ReplayChoice, fold_of


def _data(first_s: dict[int, float], end_s: float) -> SimpleNamespace:
    robots = {r: SimpleNamespace(groundtruth=np.array([[t0, 0, 0, 0], [end_s, 0, 0, 0]])) for r, t0 in first_s.items()}
    return SimpleNamespace(robots=robots, duration_s=end_s)


def test_the_two_folds_swap_what_is_calibrated_and_what_is_replayed():
    data = _data({1: 0.0, 2: 0.015, 3: 0.0}, 900.0)
    choice = ReplayChoice("set6", robots=(1, 2, 3))
    one, two = (fold_of(dataclasses.replace(choice, fold=k), data) for k in (1, 2))
    half = (0.015 + 900.0) / 2
    assert one.calibration_s == (0.015, half) and (one.start_s, one.duration_s) == (half, None)
    assert two.calibration_s == (half, 900.0) and two.start_s == 0.015
    assert two.start_s + two.duration_s == pytest.approx(half)
    assert fold_of(choice, data) is choice  # no fold: the window and calibration asked


def test_a_fold_with_a_window_or_a_calibration_of_its_own_is_refused():
    data = _data({1: 0.0}, 900.0)
    for extra in ({"start_s": 10.0}, {"duration_s": 60.0}, {"calibration_file": "cal.json"}):
        with pytest.raises(ConfigError, match="a fold sets its own window"):
            fold_of(ReplayChoice("set6", robots=(1,), fold=1, **extra), data)
    with pytest.raises(ConfigError, match="fold must be 1 or 2"):
        fold_of(ReplayChoice("set6", robots=(1,), fold=3), data)
