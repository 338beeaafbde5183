"""`swarm experiment mrclam`: a recorded MRCLAM data set replayed through the real swarm by each
estimator variant (launch.replay_setup), on several seeds of the launch priors' perturbation: dead
reckoning, the known map, the known map with cooperation, SLAM with cooperation, and the centralized
reference (one filter over every robot, in one process: ``fly_centralized``). Each variant's runs
are scored by their summary (the reference by its reference.json, in summary.json's shape):
experiment.json holds per variant the swarm RMSE and ANEES, mean and 95 % interval over the seeds,
and each robot's RMSE, block ANEES and share of NEES above the 95 % point (bus.consistency)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bus.config import SwarmConfig
from bus.errors import ConfigError
from bus.statistics import interval
from experiments.conclusions import write_experiment
from launch.replay_setup import ReplayChoice, replay_config
from launch.runspec import RunSpec

VARIANTS: dict[str, tuple[str, bool]] = {  # name: (estimator, cooperative)
    "dead-reckoning": ("dead-reckoning", False),
    "known-map": ("known-map", False),
    "known-map-coop": ("known-map", True),
    "slam-coop": ("slam", True),
    "centralized": ("centralized", True),
}
REFERENCE = "reference.json"


def plan(
    dataset: str,
    seeds: int,
    first_seed: int,
    variants: str,
    robots: str,
    start: float,
    duration: float,
    calibration: str = "",
    folds: int = 0,
) -> list[RunSpec]:
    """Every variant on every seed; the window ``start`` .. ``start + duration`` data set seconds (0
    duration: to the data set's end); ``calibration``: a frozen calibration file (else calibrated on
    the data set's first 120 s); ``folds`` 2: each run in both folds of two-fold cross-validation
    (launch.replay_setup.fold_of), its group ``<variant>-fold<k>``, instead of that window."""
    if not dataset:
        raise ConfigError("--dataset: give an MRCLAM data set (its directory or its .tar.xz)")
    specs = []
    for variant in _variants(variants):
        estimator, cooperative = VARIANTS[variant]
        for fold in _folds(folds):
            group = _group(variant, fold)
            for seed in range(first_seed, first_seed + seeds):
                choice = ReplayChoice(
                    dataset,
                    _robots(robots),
                    estimator,
                    cooperative,
                    None if fold else start,
                    None if fold else duration or None,
                    seed=seed,
                    calibration_file=calibration,
                    fold=fold,
                )
                name = f"{group}-seed{seed}"
                config = replay_config(choice, name=name).model_dump(mode="json")
                if variant == "centralized":
                    reference = {"measure": f"{__name__}:measure_reference", "runner": f"{__name__}:fly_centralized"}
                    specs.append(RunSpec(name, group, seed, config, **reference))
                else:
                    specs.append(RunSpec(name, group, seed, config))
    return specs


def _folds(folds: int) -> tuple[int, ...]:
    if folds not in (0, 2):
        raise ConfigError(f"--folds must be 2 (two-fold cross-validation) or 0, got {folds}")
    return (1, 2) if folds else (0,)


def _group(variant: str, fold: int) -> str:
    return f"{variant}-fold{fold}" if fold else variant


def fly_centralized(spec: RunSpec, config: SwarmConfig, run_dir: Path) -> list[str]:
    """The centralized reference of one seed (in this process): reference.json, in summary.json's shape."""
    import json

    from experiments.centralized_reference import run_centralized, tracks_summary

    summary = {
        "name": spec.name,
        "status": "complete",
        "reference": "centralized",
        **tracks_summary(run_centralized(config)),
    }
    (run_dir / REFERENCE).write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    return []


def measure_reference(run_dir: Path) -> dict[str, Any]:
    """The centralized reference's swarm RMSE and ANEES, for its row of the results table."""
    import json

    swarm = json.loads((run_dir / REFERENCE).read_text())["swarm"]
    return {"rmse_m": swarm["rmse_m"], "anees": swarm["anees"]}


def conclude(rows: list[dict], folder: Path, **params: Any) -> list[str]:
    """experiment.json: per variant the swarm RMSE and ANEES (mean, 95 % interval over the seeds) and
    each robot's mean RMSE; a line per variant."""
    import json

    table: dict[str, Any] = {"dataset": params["dataset"], "variants": {}}
    groups = [(v, _group(v, k)) for v in _variants(params["variants"]) for k in _folds(params.get("folds", 0))]
    for variant, group in groups:
        summaries = []
        for row in rows:
            if row.get("variant") != group or row.get("status") != "complete":
                continue
            path = folder / row["run"] / (REFERENCE if variant == "centralized" else "summary.json")
            summaries.append(json.loads(path.read_text()))
        if not summaries:
            continue
        rmse, rmse_half, n = interval([s["swarm"]["rmse_m"] for s in summaries])
        anees, anees_half, _ = interval([s["swarm"]["anees"] for s in summaries])
        robots = sorted(summaries[0]["vehicles"], key=int)
        table["variants"][group] = {
            "seeds": n,
            "rmse_m": rmse,
            "rmse_m_interval_95": rmse_half,
            "anees": anees,
            "anees_interval_95": anees_half,
            "rmse_m_per_robot": {r: sum(s["vehicles"][r]["rmse_m"] for s in summaries) / n for r in robots},
            **_consistency_per_robot(summaries, robots),
        }
    write_experiment(folder, table)
    return [
        f"  {name:<22} RMSE {v['rmse_m']:.3f} m (+- {v['rmse_m_interval_95']:.3f})  ANEES {v['anees']:.2f} "
        f"(+- {v['anees_interval_95']:.2f})  per robot "
        + " ".join(f"{x:.3f}" for x in v["rmse_m_per_robot"].values())
        + f"  block ANEES in band {v['robots_inside_band']}"
        for name, v in table["variants"].items()
    ]


def _consistency_per_robot(summaries: list[dict], robots: list[str]) -> dict[str, Any]:
    """Per robot the block ANEES and the share of NEES above the 95 % point (bus.consistency), means
    over the seeds, and how many robot runs were inside their block band ("k/n")."""
    runs = [(r, s["vehicles"][r].get("consistency") or {}) for s in summaries for r in robots]
    inside = sum(bool(c.get("inside")) for _, c in runs)

    def mean(robot: str, key: str) -> float | None:
        values = [c[key] for r, c in runs if r == robot and c.get(key) is not None]
        return sum(values) / len(values) if values else None

    return {
        "block_anees_per_robot": {r: mean(r, "block_anees") for r in robots},
        "share_above_95_per_robot": {r: mean(r, "share_above_95") for r in robots},
        "robots_inside_band": f"{inside}/{len(runs)}",
    }


def _variants(text: str) -> list[str]:
    chosen = [v.strip() for v in text.split(",") if v.strip()]
    unknown = [v for v in chosen if v not in VARIANTS]
    if unknown or not chosen:
        raise ConfigError(f"unknown variant(s) {', '.join(unknown) or '(none given)'}; known: {', '.join(VARIANTS)}")
    return chosen


def _robots(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(part) for part in text.split(",") if part.strip())
    except ValueError:
        raise ConfigError(f"--robots must be comma-separated robots 1-5, got {text!r}") from None
