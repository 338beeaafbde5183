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

from dataclasses import dataclass
from pathlib import Path

from bus.config import SwarmConfig, build_config
from bus.errors import ConfigError

ESTIMATORS = {"dead-reckoning": "ekf", "known-map": "known-map", "slam": "ekf-slam", "centralized": "known-map"}
USES_MAP = ("known-map", "centralized")
PRIOR_SIGMA_M, PRIOR_HEADING_SIGMA_RAD = 0.05, 0.02  # the start pose, surveyed (the data set's Vicon)
RATE_HZ = 50.0  # the vehicles' loop and the truth grid; clock ticks as in `swarm up` (0.5 s in lockstep:
# the same summary and metrics to the byte as 20 ms ticks on data set 6, in a quarter of the wall time)
# The robots' wheel scales are not calibrated (the first minutes turn too little to tell a scale from
# noise): a nominal 10 % datasheet spread, which known-map estimates online (vehicle.models.added_states).
ODOM_SCALE_PRIOR_SIGMA = 0.1
RANGE_SCALE_PRIOR_SIGMA = 0.05


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
    frozen = _frozen_calibration(choice)
    calibration_s = frozen.interval_s if frozen is not None else choice.calibration_s
    elsewhere = frozen is not None and not frozen.fitted_on(data)
    default_start = 0.0 if elsewhere else calibration_s[1]
    start = default_start if choice.start_s is None else choice.start_s
    end = data.duration_s if choice.duration_s is None else start + choice.duration_s
    if end <= start:
        raise ConfigError(f"the window starts at {start:g} s, after the data set's end ({data.duration_s:g} s)")
    sensors, lag, latency, cameras = _datasheet(choice, data, frozen)
    landmarks = [(int(row[0]), float(row[1]), float(row[2])) for row in data.landmarks]
    config = {
        "name": name,
        "world": {"vehicles": len(choice.robots), "seed": choice.seed, "altitude_m": 0.0},
        "clock": {"duration_s": round(end - start, 6)},
        "sensors": {
            "odom_rate_hz": RATE_HZ,
            "truth_rate_hz": RATE_HZ,
            **sensors,
            "prior_sigma_m": PRIOR_SIGMA_M,
            "odom_scale_prior_sigma": ODOM_SCALE_PRIOR_SIGMA,
            "range_scale_prior_sigma": RANGE_SCALE_PRIOR_SIGMA,
            "prior_heading_sigma_rad": PRIOR_HEADING_SIGMA_RAD,
        },
        "vehicle": {
            "estimator": ESTIMATORS[choice.estimator],
            "cooperative": choice.cooperative,
            "landmarks": landmarks if choice.estimator in USES_MAP else [],
        },
        "replay": {
            "dataset": str(choice.dataset),
            "robots": list(choice.robots),
            "start_s": start,
            "calibration_s": list(calibration_s),
            "calibration_file": choice.calibration_file,
            "calibrated_elsewhere": elsewhere,
            "odom_lag_s": lag,
            "camera_latency_s": latency,
            "sighting_sigmas": cameras,
            "withhold_landmarks": list(choice.withhold_landmarks),
            "relay_sightings": choice.relay_sightings,
        },
    }
    for section, values in (overrides or {}).items():
        config.setdefault(section, {}).update({k: v for k, v in values.items() if v is not None})
    return build_config(config)


def _frozen_calibration(choice: ReplayChoice):
    """The calibration file the user named (sim.mrclam_calibration_file), or None."""
    if not choice.calibration_file:
        return None
    from sim.mrclam_calibration_file import read_calibration

    return read_calibration(Path(choice.calibration_file))


def _datasheet(choice: ReplayChoice, data, frozen) -> tuple[dict, float, float, list[list[float]]]:
    """(the calibrated sensor fields, odometry lag s, camera latency s, each replayed robot's camera
    sigmas): read from the ``frozen`` calibration, or calibrated now on ``choice.calibration_s``."""
    if frozen is not None:
        cameras = [list(frozen.camera_of(robot)) for robot in choice.robots]
        return frozen.sensors.model_dump(), frozen.odom_lag_s, frozen.camera_latency_s, cameras
    from sim.mrclam_calibration import calibrate, sighting_sigmas
    from sim.mrclam_calibration_file import CalibratedSensors

    try:
        cal = calibrate(data, choice.calibration_s, choice.robots)
    except ValueError as exc:
        raise ConfigError(f"calibration: {exc}") from None
    sensors = {name: getattr(cal, name) for name in CalibratedSensors.model_fields}
    cameras = [list(pair) for pair in sighting_sigmas(data, choice.calibration_s, choice.robots, cal.camera_latency_s)]
    return sensors, cal.odom_lag_s, cal.camera_latency_s, cameras
