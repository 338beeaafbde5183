"""`swarm replay ...`: a recorded data set through the real swarm (launch.replay_setup)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Optional

import typer

from bus.clock_config import ClockMode
from bus.config import SwarmConfig
from bus.errors import SwarmlocError
from cli.errors import REPORT_HELP, fail
from launch.replay_setup import ESTIMATORS

replay_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Replay a recorded multi-robot data set through the swarm's real processes.",
)


def _numbers(text: str, what: str, kind=int) -> tuple:
    try:
        return tuple(kind(part) for part in text.split(",") if part.strip())
    except ValueError:
        fail(f"{what} must be comma-separated numbers, got {text!r}")


@replay_app.command("mrclam")
def mrclam(
    dataset: Path = typer.Argument(..., help="an MRCLAM data set (1-9): its directory or its .tar.xz"),
    robots: str = typer.Option("1,2,3,4,5", help="robots to replay, comma-separated; vehicle 1 is the first"),
    estimator: str = typer.Option(
        "known-map",
        help="dead-reckoning, known-map (the surveyed landmarks), slam, or "
        "centralized (the reference: one filter over every robot with the map and every "
        "robot sighting, in this process, no bus)",
    ),
    cooperative: bool = typer.Option(
        False, help="also fuse the robots' sightings of each other (covariance intersection)"
    ),
    relay: bool = typer.Option(
        True,
        help="cooperative: each sighting also reaches the robot seen, which fuses it "
        "with the observer's broadcast pose",
    ),
    start: Optional[float] = typer.Option(
        None, help="data set second the replay starts [default: the calibration's end]"
    ),
    duration: Optional[float] = typer.Option(None, help="seconds replayed [default: to the data set's end]"),
    calibrate: str = typer.Option(
        "0,120",
        help="data set interval START,END (s) the datasheet is calibrated on "
        "(odometry lag, camera latency, noise and the part of it that persists); the "
        "replayed window may not overlap it",
    ),
    calibration: Optional[Path] = typer.Option(
        None,
        help="a calibration file written by `swarm replay calibrate` (fitted on another data set, or on "
        "another interval of this one), read instead of calibrating; --calibrate is then not used",
    ),
    folds: bool = typer.Option(
        False,
        "--folds",
        help="two-fold cross-validation: calibrate on the first half of the data set and replay the "
        "second, then the other way round (two run directories, NAME-fold1 and NAME-fold2); "
        "--start, --duration, --calibrate and --calibration are then not used",
    ),
    withhold_landmarks: str = typer.Option("", help="robots whose landmark sightings are withheld, comma-separated"),
    mode: str = typer.Option("lockstep", help="lockstep (as fast as possible, reproducible) or realtime"),
    speed: float = typer.Option(1.0, help="realtime only: data set seconds per wall second"),
    seed: int = typer.Option(0, help="seed of the launch priors' perturbation"),
    out: Path = typer.Option(Path("runs"), help="parent folder of run directories"),
    name: Optional[str] = typer.Option(None, help="run directory name [default: mrclam-<estimator>]"),
    quiet: bool = typer.Option(False, help="no progress display, only the final table"),
    insecure: bool = typer.Option(False, help="no zenoh logins, no access control, no MAVLink signing"),
    report: bool = typer.Option(True, help=REPORT_HELP),
    record: bool = typer.Option(True, "--record/--no-record", help="write run.mcap"),
    live: bool = typer.Option(False, help="serve a Foxglove WebSocket live view (docs: live view)"),
    live_host: str = typer.Option("127.0.0.1", help="the live view's address"),
    live_port: int = typer.Option(8765, help="the live view's port"),
) -> None:
    """Replay the UTIAS MRCLAM data set (Leung et al., IJRR 2011): each robot a vehicle process, the
    world playing its odometry, landmark and robot sightings and Vicon truth on sim time, the ground
    station scoring. Writes a run directory and report like `swarm up`."""
    from bus.process import stop_on_signals
    from cli.results import print_result
    from launch.launcher import launch
    from launch.live import check_live_address
    from launch.replay_setup import ReplayChoice, replay_config

    if estimator not in ESTIMATORS:
        fail(f"unknown estimator {estimator!r}: use {', '.join(ESTIMATORS)}")
    if mode not in tuple(ClockMode):
        fail(f"unknown mode {mode!r}: use lockstep or realtime")
    interval = _numbers(calibrate, "--calibrate", float)
    if len(interval) != 2:
        fail(f"--calibrate must be START,END in seconds, got {calibrate!r}")
    choice = ReplayChoice(
        str(dataset),
        _numbers(robots, "--robots"),
        estimator,
        cooperative,
        start,
        duration,
        interval,
        _numbers(withhold_landmarks, "--withhold-landmarks"),
        seed,
        relay,
        str(calibration) if calibration is not None else "",
    )
    if estimator == "centralized" and mode != ClockMode.LOCKSTEP:
        fail("the centralized reference runs in this process as fast as it can: --mode realtime does not apply")
    if folds and (start is not None or duration is not None or calibration is not None or interval != (0.0, 120.0)):
        fail("--folds sets each fold's window and calibration: no --start, --duration, --calibrate, --calibration")
    base = name or f"mrclam-{estimator}{'-coop' if cooperative else ''}"
    for fold in (1, 2) if folds else (0,):
        try:
            config = replay_config(
                dataclasses.replace(choice, fold=fold),
                name=f"{base}-fold{fold}" if fold else base,
                overrides={
                    "clock": {"mode": mode, "speed": speed},
                    "view": {"record": record, "live": live, "live_host": live_host, "live_port": live_port},
                },
            )
            if config.view.live:
                check_live_address(config.view.live_host, config.view.live_port)
            if estimator == "centralized":
                _reference(config, out)
                continue
            run_dir, failures, notes = launch(
                config, out, show_progress=not quiet, stop=stop_on_signals(), secure=not insecure
            )
        except SwarmlocError as exc:
            fail(str(exc))
        print_result(run_dir, failures, notes, report=report, consistency=True)


def _reference(config: SwarmConfig, out: Path) -> None:
    """The centralized reference on the replay: a run directory with config.json and reference.json
    (per robot and swarm RMSE, max error, ANEES, in summary.json's shape), and the table printed."""
    import json

    from rich.console import Console

    from experiments.centralized_reference import run_centralized, tracks_summary
    from groundstation.display import consistency_table, rmse_table
    from launch.run_setup import unique_run_dir

    run_dir = unique_run_dir(out, config.name)
    config.dump(run_dir / "config.json")
    summary = {
        "name": config.name,
        "status": "finished",
        "reference": "centralized",
        "seed": config.world.seed,
        "duration_s": config.clock.duration_s,
        **tracks_summary(run_centralized(config)),
    }
    (run_dir / "reference.json").write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    console = Console()
    console.print(rmse_table(summary, title=f"{config.name}: centralized reference (one process, no bus)"))
    console.print(consistency_table(summary))
    console.print(f"run directory: {run_dir}")


@replay_app.command("calibrate")
def calibrate_command(
    dataset: Path = typer.Argument(..., help="an MRCLAM data set (1-9): its directory or its .tar.xz"),
    interval: str = typer.Option("0,120", help="data set interval START,END (s) to fit on"),
    robots: str = typer.Option("1,2,3,4,5", help="robots whose data it is fitted on, comma-separated"),
    out: Path = typer.Option(..., help="the calibration file to write (JSON)"),
) -> None:
    """Fit the datasheet (odometry noise and lag, camera latency, each camera's sigmas, what persists)
    on an interval of a data set against its ground truth, and freeze it in a file that `swarm replay
    mrclam --calibration FILE` reads: the other half of the data set, or another data set, is then
    replayed with numbers that never saw it (docs: real data)."""
    from rich.console import Console

    from launch.replay_setup import ReplayChoice, calibration
    from sim.mrclam import load_mrclam
    from sim.mrclam_calibration_file import dataset_name, write_calibration

    span = _numbers(interval, "--interval", float)
    chosen = _numbers(robots, "--robots")
    if len(span) != 2 or not 0 <= span[0] < span[1]:
        fail(f"--interval must be START,END in seconds with 0 <= START < END, got {interval!r}")
    if not chosen or any(r not in (1, 2, 3, 4, 5) for r in chosen) or len(set(chosen)) != len(chosen):
        fail(f"--robots must be distinct robots 1-5, got {robots!r}")
    try:
        data = load_mrclam(dataset)
        choice = ReplayChoice(str(dataset), robots=tuple(chosen), calibration_s=(span[0], span[1]))
        frozen = calibration(choice, data, dataset_name(dataset))
        write_calibration(out, frozen)
    except SwarmlocError as exc:
        fail(str(exc))
    except ValueError as exc:
        fail(f"calibration: {exc}")
    except OSError as exc:
        fail(f"cannot write {out}: {exc.strerror or exc}")
    s = frozen.sensors
    Console().print(
        f"{out}: fitted on {frozen.dataset} [{span[0]:g}, {span[1]:g}] s, robots {list(chosen)} "
        f"({frozen.sightings} landmark sightings, {frozen.odometry_windows} odometry windows): "
        f"odometry lag {frozen.odom_lag_s:.2f} s, camera latency {frozen.camera_latency_s:.2f} s, "
        f"bearing {s.bearing_sigma_rad:.4f} rad, range {s.range_sigma_m:.3f} m, "
        f"unmodelled {s.unmodelled_sigma_m:.3f} m",
        highlight=False,
    )
