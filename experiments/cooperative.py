"""`swarm experiment cooperative`: the cooperative-localization paper's experiment. A swarm (8
vehicles) loses GNSS on most of its members (6) for a long stretch (120 s); the others keep it. Each
decentralized variant flies through real processes, one run directory per variant and seed:
independent dead reckoning, naive fusion, split CI with the EKF and the UKF, split CI with IAE,
plain CI. The centralized reference (``vehicle.estimators.centralized``) runs in this process on the same
world. Scored over the jam, on the jammed vehicles only, every 0.2 s of sim time.

Consistency: ANEES is the mean pose NEES (3 dof). Its 95% interval comes from the spread of the
per-seed means (seeds are independent; vehicles of one swarm are not, since they fuse each other);
``anees_band`` is the chi-square band a consistent filter's per-instant average over all jammed runs
would lie in if those runs were independent - a reference line, narrower than the truth.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bus import statistics
from bus.config import HONEST_DATASHEET, HONEST_WORLD, SwarmConfig, build_config
from bus.errors import ConfigError
from experiments.cooperative_figures import VariantLines
from groundstation.report.rundata import load_run
from launch.runspec import RunSpec

SCORE_EVERY_US = 200_000
CENTRALIZED = "centralized"
VARIANTS: dict[str, tuple[str, dict[str, Any]]] = {
    "dead-reckoning": ("independent dead reckoning (no cooperation)", {"cooperation": {"enabled": False}}),
    "naive": ("naive fusion (double counts)", {"cooperation": {"fusion": "naive"}}),
    "ci-ekf": ("split CI, EKF", {}),
    "ci-ukf": ("split CI, UKF", {"estimator": "ukf"}),
    "ci-ekf-iae": ("split CI, EKF, IAE", {"adaptive": {"enabled": True}}),
    "plain-ci-ekf": ("plain CI, EKF", {"cooperation": {"fusion": "ci"}}),
}
LABELS = {**{name: label for name, (label, _) in VARIANTS.items()}, CENTRALIZED: "centralized reference"}


@dataclass(frozen=True)
class Setup:
    """The experiment's swarm: ``vehicles`` of which the first ``jammed`` lose GNSS from ``jam_start_s``
    for ``jam_s`` (the run ends with the jam); ``world``: "honest" (``HONEST_WORLD``) or "ideal"."""

    vehicles: int = 8
    jammed: int = 6
    jam_start_s: float = 20.0
    jam_s: float = 120.0
    world: str = "honest"

    @property
    def jammed_ids(self) -> list[int]:
        return list(range(1, self.jammed + 1))


def cooperative_config(variant: str, seed: int, setup: Setup) -> SwarmConfig:
    """One variant's swarm on ``seed``: GNSS silent for the jammed vehicles over the jam."""
    blackouts = [
        {
            "name": f"jam-v{vid}",
            "kind": "blackout",
            "vehicle": vid,
            "sensor": "gnss",
            "start_s": setup.jam_start_s,
            "for_s": setup.jam_s,
        }
        for vid in setup.jammed_ids
    ]
    sensor_truth, datasheet = (HONEST_WORLD, HONEST_DATASHEET) if setup.world == "honest" else ({}, {})
    vehicle = VARIANTS[variant][1] if variant in VARIANTS else {}
    return build_config(
        {
            "name": f"{variant}-seed{seed}",
            "world": {"vehicles": setup.vehicles, "seed": seed, "sensor_truth": sensor_truth},
            "sensors": datasheet,
            "clock": {"duration_s": setup.jam_start_s + setup.jam_s},
            "vehicle": vehicle,
            "faults": blackouts,
        }
    )


CENTRALIZED_TRACKS = "centralized.npz"  # in a centralized run's directory: per vehicle t_s, error_m, nees


def plan(
    seeds: int, first_seed: int, variants: str, vehicles: int, jammed: int, jam_start: float, jam: float, world: str
) -> list[RunSpec]:
    """Every variant on every seed (real processes), and the centralized reference on each seed's world
    (a run in one process: ``fly_centralized``)."""
    setup, chosen = _setup(variants, vehicles, jammed, jam_start, jam, world)
    specs = []
    for seed in range(first_seed, first_seed + seeds):
        for variant in chosen:
            specs.append(
                RunSpec(
                    f"{variant}-seed{seed}",
                    variant,
                    seed,
                    cooperative_config(variant, seed, setup).model_dump(mode="json"),
                    report=True,
                )
            )
        config = cooperative_config(CENTRALIZED, seed, setup).model_dump(mode="json")
        specs.append(
            RunSpec(f"{CENTRALIZED}-seed{seed}", CENTRALIZED, seed, config, runner=f"{__name__}:fly_centralized")
        )
    return specs


def fly_centralized(spec: RunSpec, config: SwarmConfig, run_dir: Path) -> list[str]:
    """The centralized reference of one seed (in this process), its tracks written to the run directory."""
    from experiments.centralized_reference import run_centralized

    tracks = run_centralized(config, score_every_us=SCORE_EVERY_US)
    arrays = {f"{key}_v{vid}": track[key] for vid, track in tracks.items() for key in ("t_s", "error_m", "nees")}
    np.savez(run_dir / CENTRALIZED_TRACKS, **arrays)
    return []


def conclude(rows: list[dict], folder: Path, **params: Any) -> list[str]:
    """experiment.json and the figures from the runs that completed; a line per variant."""
    setup, chosen = _setup(**{k: v for k, v in params.items() if k not in ("seeds", "first_seed")})
    done = {row["run"]: row for row in rows if row.get("status") == "complete"}
    seeds = range(params["first_seed"], params["first_seed"] + params["seeds"])
    runs = {v: {s: folder / f"{v}-seed{s}" for s in seeds if f"{v}-seed{s}" in done} for v in chosen}
    reference = {s: folder / f"{CENTRALIZED}-seed{s}" for s in seeds if f"{CENTRALIZED}-seed{s}" in done}
    table, figures = compare(folder, runs, {CENTRALIZED: {s: _tracks(p) for s, p in reference.items()}}, setup)
    end_s = setup.jam_start_s + setup.jam_s
    lines = [
        f"jammed vehicles {setup.jammed_ids}, {setup.jam_start_s:g}-{end_s:g} s, {len(seeds)} seed(s), "
        f"{setup.world} world:"
    ]
    for row in table["variants"].values():
        lo, hi = row["anees_interval_95"]
        lines.append(
            f"  {row['label']:<44} RMSE {row['rmse_m']:7.3f} m   ANEES {row['anees']:7.2f} [{lo:.2f}, {hi:.2f}]"
        )
    return lines + [f"figure: {f}" for f in figures]


def _setup(
    variants: str, vehicles: int, jammed: int, jam_start: float, jam: float, world: str
) -> tuple[Setup, list[str]]:
    chosen = [v.strip() for v in variants.split(",") if v.strip()]
    unknown = [v for v in chosen if v not in VARIANTS]
    if unknown or not chosen:
        raise ConfigError(f"unknown variant(s) {', '.join(unknown) or '(none given)'}; known: {', '.join(VARIANTS)}")
    if jammed > vehicles:
        raise ConfigError(f"--jammed {jammed} is more than --vehicles {vehicles}")
    if world not in ("honest", "ideal"):
        raise ConfigError(f"--world must be honest or ideal, got {world!r}")
    return Setup(vehicles=vehicles, jammed=jammed, jam_start_s=jam_start, jam_s=jam, world=world), chosen


def _tracks(run_dir: Path) -> dict[int, dict[str, np.ndarray]]:
    """A centralized run's tracks, as ``fly_centralized`` wrote them."""
    with np.load(run_dir / CENTRALIZED_TRACKS) as data:
        out: dict[int, dict[str, np.ndarray]] = {}
        for key in data.files:
            name, _, vid = key.rpartition("_v")
            out.setdefault(int(vid), {})[name] = data[key]
    return out


def jammed_tracks_of_run(run_dir: Path, setup: Setup) -> dict[int, dict[str, np.ndarray]]:
    """Per jammed vehicle of one run: t_s, error_m, nees over the jam, every 0.2 s."""
    metrics = load_run(run_dir).metrics
    if not metrics:
        return {}
    stamps = np.round(metrics["t_s"] * 1e6).astype(np.int64)
    scored = (stamps % SCORE_EVERY_US == 0) & _in_jam(metrics["t_s"], setup)
    out = {}
    for vid in setup.jammed_ids:
        keep = scored & (metrics["vehicle"] == vid)
        if keep.any():
            out[vid] = {
                "t_s": metrics["t_s"][keep],
                "error_m": metrics["err_pos_m"][keep],
                "nees": metrics["nees"][keep],
            }
    return out


def _in_jam(t_s: np.ndarray, setup: Setup) -> np.ndarray:
    return (t_s >= setup.jam_start_s) & (t_s <= setup.jam_start_s + setup.jam_s)


def jammed_tracks_of_reference(
    tracks: dict[int, dict[str, np.ndarray]], setup: Setup
) -> dict[int, dict[str, np.ndarray]]:
    """The centralized reference's tracks restricted like :func:`jammed_tracks_of_run`."""
    return {
        vid: {k: v[_in_jam(track["t_s"], setup)] for k, v in track.items()}
        for vid, track in tracks.items()
        if vid in setup.jammed_ids
    }


def summarize(tracks: dict[int, dict[int, dict[str, np.ndarray]]]) -> dict[str, Any]:
    """One variant's row from its jammed tracks [seed][vehicle]: RMSE (m), max error, ANEES with the
    95% interval from the per-seed means, the chi-square band and the share of instants inside it."""
    per_seed = [
        np.concatenate([t["nees"] for t in by_vehicle.values()]) for by_vehicle in tracks.values() if by_vehicle
    ]
    errors = np.concatenate([t["error_m"] for by_vehicle in tracks.values() for t in by_vehicle.values()])
    series = [t for by_vehicle in tracks.values() for t in by_vehicle.values()]
    length = min(len(t["nees"]) for t in series)
    instant = np.mean([t["nees"][:length] for t in series], axis=0)
    runs = len(series)
    band = np.array(statistics.chi2_band(statistics.POSE_NEES_DOF, runs=runs))
    seed_means = np.array([s.mean() for s in per_seed])
    half = 1.96 * seed_means.std(ddof=1) / np.sqrt(len(seed_means)) if len(seed_means) > 1 else float("nan")
    anees = float(np.mean(np.concatenate(per_seed)))
    return {
        "rmse_m": float(np.sqrt(np.mean(errors**2))),
        "max_error_m": float(errors.max()),
        "anees": anees,
        "anees_interval_95": [anees - half, anees + half],
        "anees_band_95": band.tolist(),
        "share_of_instants_in_band": float(np.mean((instant >= band[0]) & (instant <= band[1]))),
        "seeds": len(per_seed),
        "jammed_runs": runs,
        "samples": int(errors.size),
    }


def compare(
    folder: Path, runs: dict[str, dict[int, Path]], central: dict[str, dict[int, Any]], setup: Setup
) -> tuple[dict[str, Any], list[Path]]:
    """experiment.json (one row per variant, ratios to dead reckoning and to the centralized
    reference) and the figures; returns the table and the figure paths."""
    tracks = {
        variant: {seed: jammed_tracks_of_run(path, setup) for seed, path in by_seed.items()}
        for variant, by_seed in runs.items()
    }
    tracks |= {
        name: {seed: jammed_tracks_of_reference(t, setup) for seed, t in by_seed.items()}
        for name, by_seed in central.items()
    }
    tracks = {name: by_seed for name, by_seed in tracks.items() if any(by_seed.values())}
    rows = {name: {"label": LABELS.get(name, name), **summarize(by_seed)} for name, by_seed in tracks.items()}
    for row in rows.values():
        for base in ("dead-reckoning", CENTRALIZED):
            if base in rows:
                row[f"rmse_vs_{base}"] = row["rmse_m"] / rows[base]["rmse_m"]
    table = {"setup": setup.__dict__, "score_every_s": SCORE_EVERY_US * 1e-6, "variants": rows}
    (folder / "experiment.json").write_text(json.dumps(table, indent=2, sort_keys=True) + "\n")
    written = []
    if tracks:  # a campaign stopped before any run completed has nothing to draw
        where = f"GNSS jammed for {setup.jammed} of {setup.vehicles} vehicles from {setup.jam_start_s:g} s"
        lines = VariantLines(LABELS, CENTRALIZED, emphasised=(CENTRALIZED, "ci-ekf"), world=setup.world, jam=where)
        for stem, build in (("rmse_during_jam", lines.error_figure), ("anees_during_jam", lines.nees_figure)):
            path = folder / f"{stem}.png"
            build(tracks).savefig(path, dpi=100)
            written.append(path)
    return table, written
