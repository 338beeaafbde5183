"""The experiments, each registered once: the module that plans its runs and concludes from them, the
CPU one of its runs needs (a campaign's local cluster is sized from it) and its parameters. The
`swarm experiment` commands, with the options every campaign takes (out, quiet, live, scheduler,
workers, ...), are generated from here (cli.experiment_commands).

An experiment's own options are its ``params`` here (so that building the CLI imports no
experiment); its module provides ``plan(**params)`` (its runs, a list of launch.runspec.RunSpec, or
a one-line ConfigError) and ``conclude(rows, folder, **params)`` (from the rows of the campaign's
results table and the run directories they name: experiment.json, the figures, and the lines to
print)."""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from types import ModuleType
from typing import Any


@dataclass(frozen=True)
class Param:
    """One of an experiment's own options: ``--name`` with its default (its type) and help."""

    name: str
    default: Any
    help: str
    minimum: float | None = None


@dataclass(frozen=True)
class Experiment:
    module: str
    summary: str
    cpu_per_run: float  # cores one run keeps busy: a local campaign flies cores // this at once
    params: tuple[Param, ...] = ()


SEEDS = (
    Param("seeds", 10, "how many seeds (each flies every case)", 1),
    Param("first_seed", 1, "the first seed; the others follow", 0),
)
COOPERATIVE_VARIANTS = ("dead-reckoning", "naive", "ci-ekf", "ci-ukf", "ci-ekf-iae", "plain-ci-ekf")
LIAR_PROFILES = ("gross", "drift", "overconfident", "spoofed")
INSIDER_CONDITIONS = ("clean", "accusers", "accusers-start", "accomplice", "drift", "relapse", "stale")
MRCLAM_VARIANTS = ("dead-reckoning", "known-map", "known-map-coop", "slam-coop", "centralized")


EXPERIMENTS: dict[str, Experiment] = {
    "cooperative": Experiment(
        "experiments.cooperative",
        "The cooperative-localization paper's experiment: GNSS jammed for most of the swarm; every variant "
        "(dead reckoning, naive fusion, split CI with EKF / UKF / IAE, plain CI) on every seed through real "
        "processes, the centralized reference on the same worlds. Writes experiment.json (RMSE and ANEES over "
        "the jam, jammed vehicles) and two figures.",
        2.0,
        (
            *SEEDS,
            Param(
                "variants",
                ",".join(COOPERATIVE_VARIANTS),
                f"comma-separated variants: {', '.join(COOPERATIVE_VARIANTS)} (the centralized reference always runs)",
            ),
            Param("vehicles", 8, "swarm size", 2),
            Param("jammed", 6, "the first this many vehicles lose GNSS", 1),
            Param("jam_start", 20.0, "sim second the jam starts", 0.0),
            Param("jam", 120.0, "seconds of jam; the run ends with it", 1.0),
            Param("world", "honest", "honest (a world richer than the filters) or ideal (the filters' own models)"),
        ),
    ),
    "liar": Experiment(
        "experiments.liar",
        "A vehicle that lies to its neighbours: 8 vehicles in the honest world, vehicle 3 lying from 10 s by "
        "each profile, flown with the neighbour monitor on and off next to the clean swarm, plus no-liar runs "
        "(clean, GNSS jamming, jamming that ends, V2V link faults) to count false alarms. Writes experiment.json "
        "(honest RMSE against clean, detections, false alarms).",
        2.0,
        (
            *SEEDS,
            Param("profiles", ",".join(LIAR_PROFILES), f"comma-separated lie profiles: {', '.join(LIAR_PROFILES)}"),
            Param(
                "silenced",
                "",
                "comma-separated delays (s): also fly each profile with the liar's V2V cut that long after the lie "
                "began, the monitor off (an oracle: the best a detector that fast could do)",
            ),
        ),
    ),
    "insiders": Experiment(
        "experiments.insiders",
        "Compromised vehicles with valid keys against the trust rules: two insiders accusing every honest "
        "vehicle (5 and 8 vehicles), a drifting liar with an accomplice accusing its rangers, a liar that "
        "relapses after being caught and one that replays its own past (3 and 8 vehicles), each next to the "
        "clean swarm. Writes experiment.json (honest RMSE against clean, trust events).",
        2.0,
        (
            *SEEDS,
            Param(
                "conditions",
                ",".join(INSIDER_CONDITIONS),
                f"comma-separated conditions: {', '.join(INSIDER_CONDITIONS)}",
            ),
        ),
    ),
    "vision-slam": Experiment(
        "experiments.vision_slam",
        "The vision EKF-SLAM paper's experiment: a circle and a figure-8 UAV with GNSS jammed all flight, "
        "flown with ekf-slam on camera frames and again with dead reckoning on the same seed. Writes both runs "
        "(each with its report and landmark map), the comparison figures and experiment.json.",
        1.0,
        (
            Param("seed", 3, "seed of trajectories, sensor noise and terrain", 0),
            Param("duration", 60.0, "simulated seconds per flight", 1.0),
        ),
    ),
    "ar-slam": Experiment(
        "experiments.ar_slam",
        "The AR-EKF-SLAM paper's experiment: one camera UAV, GNSS denied, a long circle flown by full EKF-SLAM, "
        "a fixed 25 m range and the adaptive range (each association method, visual odometry, repetitive "
        "ground), and the paper's 3-D system over relief (adaptive and fixed 25 m; full 3-D EKF-SLAM when "
        "named), each case a run that feeds its estimator in one process and times it per frame. Writes "
        "experiment.json and the figures (cost per frame, squared x error, state size and NEES). Per-frame "
        "times are clean with --workers 1 (the default on 2 cores): runs side by side share the machine.",
        2.0,
        (
            Param("seed", 3, "seed of the trajectory, sensor noise and terrain", 0),
            Param("duration", 163.0, "simulated seconds (163 s: 1630 frames)", 10.0),
            Param("cases", "", "comma-separated case names (default: all but '3-D ekf-slam'; see docs/ar-slam)"),
        ),
    ),
    "lateness": Experiment(
        "experiments.lateness",
        "What late inputs cost: three vehicles with their IMU and odometry held back by each delay for most of "
        "the run, with the filters' walk of overdue inputs and without it, on every seed (lockstep: the lateness "
        "is a link fault's). Writes experiment.json (RMSE, ANEES and vehicles inside their NEES band per delay "
        "and case) and the figure of ANEES against the delay.",
        1.5,
        (
            Param("seeds", 4, "how many seeds (each flies every delay in both cases)", 1),
            Param("first_seed", 1, "the first seed; the others follow", 0),
            Param("delays", "0,0.1,0.3,0.5", "comma-separated IMU and odometry delays (s), each flown in both cases"),
            Param("duration", 60.0, "simulated seconds per run (the feed is late from 5 s on)", 6.0),
        ),
    ),
    "mrclam": Experiment(
        "experiments.mrclam",
        "A recorded MRCLAM data set replayed through the real swarm by each estimator variant (dead reckoning, "
        "the known map alone and with cooperation, SLAM with cooperation, the centralized reference in one "
        "process), on several seeds of the launch priors' perturbation. Writes experiment.json (RMSE and ANEES "
        "per variant with their 95 % intervals over the seeds, each robot's RMSE).",
        2.0,
        (
            Param("dataset", "", "an MRCLAM data set (1-9): its directory or its .tar.xz"),
            Param("seeds", 3, "how many seeds of the launch priors' perturbation", 1),
            Param("first_seed", 0, "the first seed; the others follow", 0),
            Param("variants", ",".join(MRCLAM_VARIANTS), f"comma-separated variants: {', '.join(MRCLAM_VARIANTS)}"),
            Param("robots", "1,2,3,4,5", "robots to replay, comma-separated"),
            Param("start", 120.0, "data set second the replay starts (after the calibration, 0-120 s)", 0.0),
            Param("duration", 0.0, "seconds replayed (0: to the data set's end)", 0.0),
            Param("calibration", "", "a file from `swarm replay calibrate` read instead of calibrating on 0-120 s"),
            Param(
                "folds",
                0,
                "2: two-fold cross-validation, every run in both folds (calibrated on one half of the data set, "
                "scored on the other); --start and --duration are then not used",
                0,
            ),
        ),
    ),
}


def module_of(name: str) -> ModuleType:
    return importlib.import_module(EXPERIMENTS[name].module)
