"""`swarm experiment ...`: the papers' experiments, each a folder of ordinary run directories (with
their reports) plus comparison figures and a JSON table (``experiments.vision_slam``)."""

from __future__ import annotations

import json
from pathlib import Path

import typer

from bus.errors import SwarmlocError
from cli.errors import fail

VARIANT_NAMES = (
    "dead-reckoning",
    "naive",
    "ci-ekf",
    "ci-ukf",
    "ci-ekf-iae",
    "plain-ci-ekf",
)  # experiment_cooperative.VARIANTS

LIVE_HELP = "serve each run's Foxglove WebSocket live view in turn, at real time (docs: live view)"


def live_view(live: bool, host: str, port: int):
    """The runs' view with the live view on (its address checked now, a one-line error), or None. A
    lockstep run with a viewer is paced at real time (``view.live_speed``), so that each run of an
    experiment can be watched rather than flash by in seconds."""
    if not live:
        return None
    from bus.config import ViewConfig
    from launch.live import check_live_address

    try:
        check_live_address(host, port)
    except SwarmlocError as exc:
        fail(str(exc))
    return ViewConfig(live=True, live_host=host, live_port=port, live_speed=1.0)


experiment_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Experiments from the papers, each a folder of ordinary runs plus comparison figures.",
)


@experiment_app.command("vision-slam")
def vision_slam(
    out: Path = typer.Option(Path("runs"), help="parent folder of the experiment folder"),
    seed: int = typer.Option(3, help="seed of trajectories, sensor noise and terrain"),
    duration: float = typer.Option(60.0, help="simulated seconds per flight"),
    quiet: bool = typer.Option(False, help="no progress display"),
    live: bool = typer.Option(False, help=LIVE_HELP),
    live_host: str = typer.Option("127.0.0.1", help="the live view's address"),
    live_port: int = typer.Option(8765, help="the live view's port"),
) -> None:
    """The vision EKF-SLAM paper's experiment: a circle and a figure-8 UAV with GNSS jammed all flight,
    flown with ekf-slam on camera frames and again with dead reckoning on the same seed. Writes both
    runs (each with its report and landmark map), the comparison figures and experiment.json."""
    from rich.console import Console

    from bus.process import stop_on_signals
    from experiments.vision_slam import compare, run_vision_slam
    from groundstation.display import report_and_say

    try:
        view = live_view(live, live_host, live_port)
        folder, runs, failures = run_vision_slam(
            out, seed=seed, duration_s=duration, stop=stop_on_signals(), show_progress=not quiet, view=view
        )
    except SwarmlocError as exc:
        fail(str(exc))
    console = Console()
    ok = all(report_and_say(run, console) for run in runs.values())
    table, figures = compare(folder, runs)
    for name, flight in table.items():
        landmarks = {vid: v.get("landmarks") for vid, v in flight["vehicles"].items()}
        console.print(
            f"{name}: {flight['status']}, swarm RMSE {flight['swarm_rmse_m']} m, ANEES {flight['swarm_anees']}"
            + (f", landmarks {landmarks}" if any(landmarks.values()) else ""),
            highlight=False,
        )
    for failure in failures:
        console.print(f"[red]swarm: {failure}[/red]")
    for figure in figures:
        console.print(f"figure: {figure}")
    console.print(f"experiment: {folder}")
    if failures or not ok:
        raise typer.Exit(1)


@experiment_app.command("cooperative")
def cooperative(
    out: Path = typer.Option(Path("runs"), help="parent folder of the experiment folder"),
    seeds: int = typer.Option(10, min=1, max=1000, help="how many seeds (each flies every variant)"),
    first_seed: int = typer.Option(1, min=0, help="the first seed; the others follow"),
    variants: str = typer.Option(
        ",".join(VARIANT_NAMES),
        help="comma-separated variants to fly: "
        + ", ".join(VARIANT_NAMES)
        + " (the centralized reference always runs)",
    ),
    vehicles: int = typer.Option(8, min=2, max=250, help="swarm size"),
    jammed: int = typer.Option(6, min=1, help="the first this many vehicles lose GNSS"),
    jam_start: float = typer.Option(20.0, min=0.0, help="sim second the jam starts"),
    jam: float = typer.Option(120.0, min=1.0, help="seconds of jam; the run ends with it"),
    world: str = typer.Option(
        "honest", help="honest (a world richer than the filters: world.sensor_truth) or ideal (the filters' own models)"
    ),
    quiet: bool = typer.Option(False, help="no progress display"),
    live: bool = typer.Option(False, help=LIVE_HELP),
    live_host: str = typer.Option("127.0.0.1", help="the live view's address"),
    live_port: int = typer.Option(8765, help="the live view's port"),
) -> None:
    """The cooperative-localization paper's experiment: GNSS jammed for most of the swarm; every
    variant (dead reckoning, naive fusion, split CI with EKF / UKF / IAE, plain CI) flies on every seed
    through real processes, the centralized reference runs on the same worlds. Writes each run (with
    its report), experiment.json (RMSE and ANEES over the jam, jammed vehicles) and two figures."""
    from rich.console import Console

    from bus.process import stop_on_signals
    from experiments.cooperative import Setup, compare, run_cooperative
    from groundstation.display import report_and_say

    chosen = [v.strip() for v in variants.split(",") if v.strip()]
    unknown = [v for v in chosen if v not in VARIANT_NAMES]
    if unknown or not chosen:
        fail(f"unknown variant(s) {', '.join(unknown) or '(none given)'}; known: {', '.join(VARIANT_NAMES)}")
    if jammed > vehicles:
        fail(f"--jammed {jammed} is more than --vehicles {vehicles}")
    if world not in ("honest", "ideal"):
        fail(f"--world must be honest or ideal, got {world!r}")
    setup = Setup(vehicles=vehicles, jammed=jammed, jam_start_s=jam_start, jam_s=jam, world=world)
    try:
        folder, runs, central, failures = run_cooperative(
            out,
            seeds=list(range(first_seed, first_seed + seeds)),
            variants=chosen,
            setup=setup,
            stop=stop_on_signals(),
            show_progress=not quiet,
            view=live_view(live, live_host, live_port),
        )
        table, figures = compare(folder, runs, central, setup)
    except SwarmlocError as exc:
        fail(str(exc))
    console = Console()
    reported = [report_and_say(run, console) for by_seed in runs.values() for run in by_seed.values()]
    console.print(
        f"jammed vehicles {setup.jammed_ids}, {jam_start:g}-{jam_start + jam:g} s, {seeds} seed(s), {world} world:",
        highlight=False,
    )
    for row in table["variants"].values():
        lo, hi = row["anees_interval_95"]
        console.print(
            f"  {row['label']:<44} RMSE {row['rmse_m']:7.3f} m   ANEES {row['anees']:7.2f} [{lo:.2f}, {hi:.2f}]",
            highlight=False,
        )
    for failure in failures:
        console.print(f"[red]swarm: {failure}[/red]")
    for figure in figures:
        console.print(f"figure: {figure}")
    console.print(f"experiment: {folder}")
    if failures or not all(reported):
        raise typer.Exit(1)


@experiment_app.command("liar")
def liar(
    out: Path = typer.Option(Path("runs"), help="parent folder of the experiment folder"),
    seeds: int = typer.Option(10, min=1, max=1000, help="how many seeds (each flies every case)"),
    first_seed: int = typer.Option(1, min=0, help="the first seed; the others follow"),
    profiles: str = typer.Option(
        "gross,drift,overconfident,spoofed", help="comma-separated lie profiles: gross, drift, overconfident, spoofed"
    ),
    silenced: str = typer.Option(
        "",
        help="comma-separated delays (s): also fly each profile with the liar's V2V cut that long after "
        "the lie began, the monitor off (an oracle: the best a detector that fast could do)",
    ),
    quiet: bool = typer.Option(False, help="no progress display"),
    live: bool = typer.Option(False, help=LIVE_HELP),
    live_host: str = typer.Option("127.0.0.1", help="the live view's address"),
    live_port: int = typer.Option(8765, help="the live view's port"),
) -> None:
    """A vehicle that lies to its neighbours: 8 vehicles in the honest world, vehicle 3 lying from 10 s
    by each profile, flown with the neighbour monitor on and off next to the clean swarm, plus no-liar
    runs (clean, GNSS jamming, jamming that ends, V2V link faults) to count false alarms. Writes every run and
    experiment.json (honest RMSE against clean, detections, false alarms)."""
    from rich.console import Console

    from bus.process import stop_on_signals
    from experiments.liar import PROFILES, run_liar, summarize

    chosen = tuple(p.strip() for p in profiles.split(",") if p.strip())
    unknown = [p for p in chosen if p not in PROFILES]
    if unknown or not chosen:
        fail(f"unknown profile(s) {', '.join(unknown) or '(none given)'}; known: {', '.join(PROFILES)}")
    delays = _delays(silenced)
    try:
        folder, runs, failures = run_liar(
            out,
            seeds=list(range(first_seed, first_seed + seeds)),
            stop=stop_on_signals(),
            show_progress=not quiet,
            profiles=chosen,
            silenced=delays,
            view=live_view(live, live_host, live_port),
        )
        table = summarize(runs)
    except SwarmlocError as exc:
        fail(str(exc))
    (folder / "experiment.json").write_text(json.dumps(table, indent=2, sort_keys=True) + "\n")
    console = Console()
    for name, row in table["conditions"].items():
        ratio, worst = row["honest_rmse_vs_clean_mean"], row["honest_rmse_vs_clean_max"]
        detected = row["rangers_that_distrusted_the_liar"]
        delay = f"median {row['detection_s_median']} s, max {row['detection_s_max']} s"
        console.print(
            f"  {name:<26} honest RMSE / clean {ratio} (max {worst})  liar distrusted by {detected} ({delay})"
            f"  false alarms {row['false_alarms']}",
            highlight=False,
        )
    for failure in failures:
        console.print(f"[red]swarm: {failure}[/red]")
    console.print(f"experiment: {folder}")
    if failures:
        raise typer.Exit(1)


@experiment_app.command("insiders")
def insiders(
    out: Path = typer.Option(Path("runs"), help="parent folder of the experiment folder"),
    seeds: int = typer.Option(10, min=1, max=1000, help="how many seeds (each flies every case)"),
    first_seed: int = typer.Option(1, min=0, help="the first seed; the others follow"),
    conditions: str = typer.Option(
        "clean,accusers,accomplice,drift,relapse,stale",
        help="comma-separated conditions: clean, accusers, accomplice, drift, relapse, stale",
    ),
    quiet: bool = typer.Option(False, help="no progress display"),
    live: bool = typer.Option(False, help=LIVE_HELP),
    live_host: str = typer.Option("127.0.0.1", help="the live view's address"),
    live_port: int = typer.Option(8765, help="the live view's port"),
) -> None:
    """Compromised vehicles with valid keys against the trust rules: two insiders accusing every honest
    vehicle (5 and 8 vehicles), a drifting liar with an accomplice accusing its rangers, a liar that
    relapses after being caught and one that replays its own past (3 and 8 vehicles), each next to the
    clean swarm. Writes every run and experiment.json (honest RMSE against clean, trust events)."""
    from rich.console import Console

    from bus.process import stop_on_signals
    from experiments.insiders import CONDITIONS, run_insiders, summarize

    chosen = tuple(c.strip() for c in conditions.split(",") if c.strip())
    unknown = [c for c in chosen if c not in CONDITIONS]
    if unknown or not chosen:
        fail(f"unknown condition(s) {', '.join(unknown) or '(none given)'}; known: {', '.join(CONDITIONS)}")
    try:
        folder, runs, failures = run_insiders(
            out,
            seeds=list(range(first_seed, first_seed + seeds)),
            stop=stop_on_signals(),
            show_progress=not quiet,
            conditions=tuple(dict.fromkeys(("clean", *chosen))),
            view=live_view(live, live_host, live_port),
        )
        table = summarize(runs)
    except SwarmlocError as exc:
        fail(str(exc))
    (folder / "experiment.json").write_text(json.dumps(table, indent=2, sort_keys=True) + "\n")
    console = Console()
    for name, row in table["conditions"].items():
        console.print(
            f"  {name:<24} honest RMSE / clean {row['honest_rmse_vs_clean_mean']}"
            f" (max {row['honest_rmse_vs_clean_max']})"
            f"  honest distrusting honest {row['honest_distrusting_honest']}  distrust/trust events"
            f" {row['distrust_events']}/{row['trust_events']}  contradicted insiders {row['contradicted_insiders']}"
            f" honest {row['contradicted_honest']}",
            highlight=False,
        )
    for failure in failures:
        console.print(f"[red]swarm: {failure}[/red]")
    console.print(f"experiment: {folder}")
    if failures:
        raise typer.Exit(1)


def _delays(text: str) -> tuple[float, ...]:
    """--silenced's delays (s), each a number from 0 to the lie's length; a one-line error otherwise."""
    from experiments.liar import DURATION_S, LIE_START_S

    delays = []
    for item in (t.strip() for t in text.split(",") if t.strip()):
        try:
            delay = float(item)
        except ValueError:
            fail(f"--silenced: {item!r} is not a number of seconds")
        if not 0.0 <= delay <= DURATION_S - LIE_START_S:
            fail(f"--silenced: {item} s is outside 0 to {DURATION_S - LIE_START_S:g} s (the lie's length)")
        delays.append(delay)
    return tuple(dict.fromkeys(delays))


@experiment_app.command("ar-slam")
def ar_slam(
    out: Path = typer.Option(Path("runs"), help="parent folder of the experiment folder"),
    seed: int = typer.Option(3, help="seed of the trajectory, sensor noise and terrain"),
    duration: float = typer.Option(163.0, min=10.0, max=3600.0, help="simulated seconds (163 s: 1630 frames)"),
    cases: str = typer.Option("", help="comma-separated case names (default: all; see docs/ar-slam)"),
    quiet: bool = typer.Option(False, help="no progress display"),
) -> None:
    """The AR-EKF-SLAM paper's experiment: one camera UAV, GNSS denied, a long circle flown by full
    EKF-SLAM, a fixed 25 m range and the adaptive range (each association method, visual odometry,
    repetitive ground), each estimator timed per frame in this process. Writes experiment.json and
    the figures (cost per frame, squared x error, state size and NEES)."""
    from rich.console import Console

    from experiments.ar_slam import CASES, run_ar_slam, write_figures
    from launch.launcher import unique_run_dir

    chosen = tuple(c.strip() for c in cases.split(",") if c.strip())
    known = {c.name: c for c in CASES}
    unknown = [c for c in chosen if c not in known]
    if unknown:
        fail(f"unknown case(s) {', '.join(unknown)}; known: {', '.join(known)}")
    console = Console()
    folder = unique_run_dir(out, "ar-slam")
    try:
        table, tracks = run_ar_slam(
            folder,
            seed=seed,
            duration_s=duration,
            cases=tuple(known[c] for c in chosen) if chosen else CASES,
            progress=(lambda _: None) if quiet else (lambda text: console.print(text, highlight=False)),
        )
    except SwarmlocError as exc:
        fail(str(exc))
    (folder / "experiment.json").write_text(json.dumps(table, indent=2, sort_keys=True) + "\n")
    for name, row in table["cases"].items():
        console.print(
            f"  {name:<28} RMSE {row['rmse_m']} m  ANEES {row['anees']}  state <= {row['state_dim_max']}"
            f"  frame p50/p99 {row['frame_ms_p50']}/{row['frame_ms_p99']} ms  correct {row['correct_rate']}"
            f"  false {row['false_pairs']}",
            highlight=False,
        )
    for figure in write_figures(folder, tracks):
        console.print(f"figure: {figure}")
    console.print(f"experiment: {folder}")
