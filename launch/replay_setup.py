"""The swarm configuration of a data-set replay (``swarm replay mrclam``): the recorded robots as
vehicles, the datasheet calibrated on an interval of the data set that is then not replayed
(sim.mrclam_calibration), and the estimator variant.

Variants: ``dead-reckoning`` (the ``ekf`` on odometry alone), ``known-map`` (landmark sightings against
the surveyed landmarks of ``Landmark_Groundtruth.dat``), ``slam`` (``ekf-slam``: the landmarks are
mapped as they are seen); ``cooperative`` adds the robots' sightings of each other, fused with
covariance intersection against the seen robot's broadcast estimate. ``centralized`` is the
reference (experiments.centralized_reference): one filter over every robot, run in one process,
with known-map's models, the surveyed landmarks and every robot-to-robot sighting fused exactly.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from bus.config import SwarmConfig, build_config
from bus.errors import ConfigError
from bus.estimators import ESTIMATORS as REGISTRY

# what `swarm replay mrclam --estimator` offers: a registry estimator (bus.estimators) by the replay's name for it
ESTIMATORS = {"dead-reckoning": "ekf", "known-map": "known-map", "slam": "ekf-slam", "centralized": "known-map"}
PRIOR_SIGMA_M, PRIOR_HEADING_SIGMA_RAD = 0.05, 0.02  # the start pose, surveyed (the data set's Vicon)
RATE_HZ = 50.0  # the vehicles' loop and the truth grid; clock ticks as in `swarm up` (0.5 s in lockstep:
# the same summary and metrics to the byte as 20 ms ticks on data set 6, in a quarter of the wall time)
# The robots' wheel scales are not calibrated (the first minutes turn too little to tell a scale from
# noise): a nominal 10 % datasheet spread, which known-map estimates online (vehicle.models.added_states).
ODOM_SCALE_PRIOR_SIGMA = 0.1
RANGE_SCALE_PRIOR_SIGMA = 0.05
# A data set's odometry is the robots' commands, logged at an irregular rate (gaps of 20 ms to 1 s): each
# is held until the next by design, and what holding it costs is in the calibrated noise, not a walk.
HELD_COMMANDS = {"speed_walk_mps_rtsec": 0.0, "yaw_rate_walk_radps_rtsec": 0.0}


@dataclass(frozen=True)
class ReplayChoice:
    """What the user asked for: robots, window (data set seconds; None: to the end), estimator."""

    dataset: str
    robots: tuple[int, ...] = (1, 2, 3, 4, 5)
    estimator: str = "known-map"
    cooperative: bool = False
    start_s: float | None = None
    duration_s: float | None = None
    calibration_s: tuple[float, float] = (0.0, 120.0)
    withhold_landmarks: tuple[int, ...] = ()
    seed: int = 0
    relay_sightings: bool = True
    calibration_file: str = ""  # a datasheet frozen by `swarm replay calibrate` ("": calibrate on calibration_s)
    fold: int = 0  # 1, 2: that fold of two-fold cross-validation (fold_of); 0: the window and calibration asked


def replay_config(choice: ReplayChoice, *, name: str, overrides: dict | None = None) -> SwarmConfig:
    """Load the data set, calibrate (or read the frozen calibration), and build the validated config
    (ConfigError, DataError name the problem). With a calibration fitted on another data set the window
    starts at 0 by default; on this one, where its interval ends, and may not overlap it."""
    from sim.mrclam import load_mrclam

    if choice.estimator not in ESTIMATORS:
        raise ConfigError(f"unknown estimator {choice.estimator!r}: use {', '.join(ESTIMATORS)}")
    if (
        not choice.robots
        or any(r not in (1, 2, 3, 4, 5) for r in choice.robots)
        or len(set(choice.robots)) != len(choice.robots)
    ):
        raise ConfigError(f"robots must be distinct robots 1-5, got {list(choice.robots)}")
    if any(r not in choice.robots for r in choice.withhold_landmarks):
        raise ConfigError(f"--withhold-landmarks {list(choice.withhold_landmarks)} names robots not replayed")
    data = load_mrclam(choice.dataset)
    choice = fold_of(choice, data)
    frozen = _frozen_calibration(choice)
    calibration_s = frozen.interval_s if frozen is not None else choice.calibration_s
    elsewhere = frozen is not None and not frozen.fitted_on(data)
    default_start = 0.0 if elsewhere else calibration_s[1]
    start = default_start if choice.start_s is None else choice.start_s
    end = data.duration_s if choice.duration_s is None else start + choice.duration_s
    if end <= start:
        raise ConfigError(f"the window starts at {start:g} s, after the data set's end ({data.duration_s:g} s)")
    sheet = _read_datasheet(choice, frozen) if frozen is not None else calibrated_datasheet(choice, data)
    config = _config_dict(choice, name, data, sheet, (start, end), calibration_s)
    config["replay"]["calibrated_elsewhere"] = elsewhere
    for section, values in (overrides or {}).items():
        config.setdefault(section, {}).update({k: v for k, v in values.items() if v is not None})
    return build_config(config)


def fold_of(choice: ReplayChoice, data) -> ReplayChoice:
    """The choice's fold of two-fold cross-validation on ``data`` (sim.mrclam.MrclamData), from the
    first second every replayed robot has ground truth to the data set's end: fold 1 calibrates on
    the first half and replays the second, fold 2 the other way round, so that no fold replays what
    it was calibrated on; the choice itself when it names no fold. ConfigError when a fold is asked
    with a window or a calibration of its own."""
    if not choice.fold:
        return choice
    if choice.fold not in (1, 2):
        raise ConfigError(f"fold must be 1 or 2 (two-fold cross-validation), got {choice.fold}")
    if choice.start_s is not None or choice.duration_s is not None or choice.calibration_file:
        raise ConfigError("a fold sets its own window and calibration: no start, duration or calibration file")
    logs = [data.robots[r].groundtruth for r in choice.robots if r in data.robots]
    first = max((float(truth[0, 0]) for truth in logs if len(truth)), default=0.0)
    half = (first + data.duration_s) / 2.0
    if choice.fold == 1:
        return dataclasses.replace(choice, calibration_s=(first, half), start_s=half)
    return dataclasses.replace(choice, calibration_s=(half, data.duration_s), start_s=first, duration_s=half - first)


@dataclass(frozen=True)
class Datasheet:
    """What a calibration gives a replay: the ``sensors`` fields, the odometry lag and camera latency
    (s), and per replayed robot its camera's sigmas [range per metre, bearing rad] and readout."""

    sensors: dict
    odom_lag_s: float
    camera_latency_s: float
    sighting_sigmas: list[list[float]]
    readouts: list[dict]


def _config_dict(
    choice: ReplayChoice,
    name: str,
    data,
    sheet: Datasheet,
    window_s: tuple[float, float],
    calibration_s: tuple[float, float],
) -> dict:
    """The config (as a dict) replaying ``window_s`` of ``data`` with ``sheet``."""
    start, end = window_s
    estimator = ESTIMATORS[choice.estimator]
    landmarks = [(int(row[0]), float(row[1]), float(row[2])) for row in data.landmarks]
    return {
        "name": name,
        "world": {"vehicles": len(choice.robots), "seed": choice.seed, "altitude_m": 0.0},
        "clock": {"duration_s": round(end - start, 6)},
        "sensors": {
            "odom_rate_hz": RATE_HZ,
            "truth_rate_hz": RATE_HZ,
            **HELD_COMMANDS,
            **sheet.sensors,
            "prior_sigma_m": PRIOR_SIGMA_M,
            "odom_scale_prior_sigma": ODOM_SCALE_PRIOR_SIGMA,
            "range_scale_prior_sigma": RANGE_SCALE_PRIOR_SIGMA,
            "prior_heading_sigma_rad": PRIOR_HEADING_SIGMA_RAD,
        },
        "vehicle": {
            "estimator": estimator,
            "cooperation": {"enabled": choice.cooperative},
            "landmarks": landmarks if "map" in REGISTRY[estimator].needs else [],
        },
        "replay": {
            "dataset": str(choice.dataset),
            "robots": list(choice.robots),
            "start_s": start,
            "calibration_s": list(calibration_s),
            "calibration_file": choice.calibration_file,
            "odom_lag_s": sheet.odom_lag_s,
            "camera_latency_s": sheet.camera_latency_s,
            "sighting_sigmas": sheet.sighting_sigmas,
            "readouts": sheet.readouts,
            "withhold_landmarks": list(choice.withhold_landmarks),
            "relay_sightings": choice.relay_sightings,
        },
    }


def _frozen_calibration(choice: ReplayChoice):
    """The calibration file the user named (sim.mrclam_calibration_file), or None."""
    if not choice.calibration_file:
        return None
    from sim.mrclam_calibration_file import read_calibration

    return read_calibration(Path(choice.calibration_file))


def _read_datasheet(choice: ReplayChoice, frozen) -> Datasheet:
    """The datasheet of the ``frozen`` calibration (sim.mrclam_calibration_file) for the replayed robots."""
    return Datasheet(
        frozen.sensors.model_dump(),
        frozen.odom_lag_s,
        frozen.camera_latency_s,
        [list(frozen.camera_of(robot)) for robot in choice.robots],
        [frozen.readout_of(robot).model_dump() for robot in choice.robots],
    )


def calibrated_datasheet(choice: ReplayChoice, data) -> Datasheet:
    """The datasheet calibrated on ``choice.calibration_s`` of ``data`` (:func:`calibration`), now or
    by an earlier replay of the same data and code (launch.calibration_cache)."""
    from launch.calibration_cache import cache_folder, remembered

    asked = calibration_inputs(choice)
    frozen = remembered(data, repr(asked), lambda: calibration(choice, data, asked.dataset), cache_folder())
    return _read_datasheet(choice, frozen)


def calibration_inputs(choice: ReplayChoice) -> ReplayChoice:
    """What of ``choice`` :func:`calibration` reads: the choice with the fields it does not read made
    the same for every replay (the estimator and its variant, which :func:`_known_map_config` sets
    for the held-out replays; the window: theirs are inside the interval; the data set's path,
    which they only record: its name is kept). The robots, the interval, the seed of the launch
    priors, the relay of sightings, and any field added later stay."""
    from sim.mrclam_calibration_file import dataset_name

    return dataclasses.replace(
        choice,
        dataset=dataset_name(choice.dataset),
        estimator="known-map",
        cooperative=False,
        start_s=None,
        duration_s=None,
        withhold_landmarks=(),
    )


def calibration(choice: ReplayChoice, data, dataset: str):
    """The calibration of ``choice.robots`` on ``choice.calibration_s`` of ``data`` (named
    ``dataset``) as a file would hold it (sim.mrclam_calibration_file): the datasheet fitted against
    the ground truth on the whole interval (sim.mrclam_calibration), and what it leaves uncovered,
    measured where it is used, out of sample (:func:`held_out_sigma`). ConfigError when the interval
    holds too little."""
    from sim.mrclam_calibration_file import calibration_file

    cal, sigmas = _fitted(choice, data)
    return calibration_file(data, dataset, cal, choice.robots, sigmas, held_out_sigma(choice, data, dataset))


def _fitted(choice: ReplayChoice, data) -> tuple:
    """(sim.mrclam_calibration's calibration, each robot's camera sigmas) on ``choice.calibration_s``."""
    from sim.mrclam_calibration import calibrate, sighting_sigmas

    try:
        cal = calibrate(data, choice.calibration_s, choice.robots)
    except ValueError as exc:
        raise ConfigError(f"calibration: {exc}") from None
    return cal, sighting_sigmas(data, choice.calibration_s, choice.robots, cal.camera_latency_s, cal.readouts)


def held_out_sigma(choice: ReplayChoice, data, dataset: str) -> float:
    """The unmodelled sigma (launch.unmodelled) of a calibration on ``choice.calibration_s``,
    cross-validated inside it: a datasheet fitted on part of it replays the rest (known-map,
    :func:`held_out_folds`), and the sigma is fitted on all the replays' errors together; 0 when a
    part holds too little to calibrate on or to replay."""
    from launch.unmodelled import position_errors, unmodelled_sigma
    from sim.mrclam_calibration_file import calibration_file

    errors, covariances = [], []
    for fit_on, replay_on in held_out_folds(*choice.calibration_s):
        part = dataclasses.replace(choice, calibration_s=fit_on)
        try:
            cal, sigmas = _fitted(part, data)
        except ConfigError:
            return 0.0
        sheet = _read_datasheet(part, calibration_file(data, dataset, cal, choice.robots, sigmas, 0.0))
        config = _known_map_config(part, data, sheet, replay_on)
        if config is None:
            return 0.0
        e, c = position_errors(config, data)
        errors.append(e)
        covariances.append(c)
    return unmodelled_sigma(errors, covariances)


def held_out_folds(low: float, high: float) -> list[tuple[tuple[float, float], tuple[float, float]]]:
    """(interval fitted on, interval replayed) pairs inside [low, high]: each half replayed with the
    datasheet of the other, and each outer third with that of the two thirds beside it (repeated
    cross-validation: one split's answer depends on which minutes it holds out)."""
    half, third = low + (high - low) / 2, (high - low) / 3
    return [
        ((low, half), (half, high)),
        ((half, high), (low, half)),
        ((low, high - third), (high - third, high)),
        ((low + third, high), (low, low + third)),
    ]


def _known_map_config(
    choice: ReplayChoice, data, sheet: Datasheet, window_s: tuple[float, float]
) -> SwarmConfig | None:
    """The known-map replay of ``window_s`` (outside ``choice.calibration_s``) with ``sheet``, from the
    first instant Vicon has every robot; None when that leaves nothing of the window."""
    low, high = window_s
    first_truths = [float(data.robots[r].groundtruth[0, 0]) for r in choice.robots if len(data.robots[r].groundtruth)]
    start = max([low, *first_truths])
    if start >= high:
        return None
    known_map = dataclasses.replace(choice, estimator="known-map", cooperative=False, withhold_landmarks=())
    end = high - 1e-5  # clear of a calibration interval starting there, whatever the rounding of its duration
    return build_config(_config_dict(known_map, "held-out", data, sheet, (start, end), choice.calibration_s))
