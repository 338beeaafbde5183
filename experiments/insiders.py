"""`swarm experiment insiders`: compromised vehicles with valid keys against the trust rules
(docs/security.md), beside `swarm experiment liar`.

Vehicles of the honest world (``HONEST_WORLD``, ``HONEST_DATASHEET``), real processes in lockstep,
``DURATION_S`` each; from ``START_S`` on, by condition:

- ``accusers``: vehicles 3 and 4 keep their positions honest and accuse every honest vehicle in each
  broadcast (the ``accuse`` fault), in swarms of 5 and 8; ``accusers-start``: the same from the
  first second, in a swarm of 5 told the default f = 1 (two accusers are a quorum: what a new user
  meets), before any vehicle has ranged anyone;
- ``accomplice``: vehicle 3 drifts (0.15 m/s) while vehicle 4 accuses the honest vehicles that
  range vehicle 3 (read off the pure world of the same seed), 8 vehicles; beside it ``drift``, the
  liar alone;
- ``relapse``: vehicle 3 lies grossly for 8 s (30 m, its covariance 100x too small), then drifts
  0.15 m/s from a zero offset, in swarms of 3 and 8;
- ``stale``: vehicle 3 rebroadcasts its estimate of 5 s before, covariance as it was, in swarms of 3 and 8.

Each flies under the trust rule (``evidence``, told f = 2: two insiders at most), and for comparison
the accusers under the rule it replaced (``quorum-only`` with f = 1: a quorum of two decides) and the
liars with the monitor off (``off``), next to the clean swarm of the same seed and size. Scored from
``START_S`` to the end on every vehicle but 3 and 4 (``SCORED_OUT``: the insiders of every condition,
so that the liar alone and the liar with an accomplice are scored on the same vehicles), against the
clean run's same vehicles.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bus.config import HONEST_DATASHEET, HONEST_WORLD, SwarmConfig, build_config
from bus.errors import ConfigError
from experiments.conclusions import completed, write_experiment
from groundstation.report.rundata import load_run
from launch.runspec import RunSpec

LIAR, ACCOMPLICE = 3, 4
SCORED_OUT = (LIAR, ACCOMPLICE)
START_S = 10.0
DURATION_S = 180.0
GROSS_S = 8.0
DRIFT = {"drift_mps": 0.15, "heading_deg": 45.0}
CONDITIONS: dict[str, tuple[tuple[int, ...], tuple[str, ...]]] = {  # sizes, rules (registry: INSIDER_CONDITIONS)
    "clean": ((3, 5, 8), ("evidence",)),
    "accusers": ((5, 8), ("evidence", "quorum-only")),
    "accusers-start": ((5,), ("default",)),
    "accomplice": ((8,), ("evidence",)),
    "drift": ((8,), ("evidence", "off")),
    "relapse": ((3, 8), ("evidence", "off")),
    "stale": ((3, 8), ("evidence", "off")),
}


@dataclass(frozen=True)
class Case:
    condition: str
    vehicles: int
    rule: str  # evidence | quorum-only | off (the monitor off) | default (f = 1)
    seed: int

    @property
    def group(self) -> str:
        return f"{self.condition}-{self.vehicles}-{self.rule}"

    @property
    def name(self) -> str:
        return f"{self.group}-seed{self.seed}"

    @property
    def insiders(self) -> tuple[int, ...]:
        """The compromised vehicles (left out of the score)."""
        two = (LIAR, ACCOMPLICE)
        return {"clean": (), "accusers": two, "accusers-start": two, "accomplice": two}.get(self.condition, (LIAR,))


def cases(seeds: list[int], conditions: tuple[str, ...] = tuple(CONDITIONS)) -> list[Case]:
    """Every run: each condition at each of its sizes under each of its rules, per seed."""
    return [
        Case(condition, n, rule, seed)
        for seed in seeds
        for condition in conditions
        for n in CONDITIONS[condition][0]
        for rule in CONDITIONS[condition][1]
    ]


def faults(case: Case) -> list[dict[str, Any]]:
    """The case's fault plan."""
    honest = [v for v in range(1, case.vehicles + 1) if v not in case.insiders]
    at = {"start_s": START_S}
    if case.condition.startswith("accusers"):
        at = {"start_s": 0.0} if case.condition == "accusers-start" else at
        return [{"name": f"accuse-v{v}", "kind": "accuse", "vehicle": v, "names": honest, **at} for v in case.insiders]
    drift = {"name": "liar", "kind": "lie", "vehicle": LIAR, **DRIFT, **at}
    if case.condition == "drift":
        return [drift]
    if case.condition == "accomplice":
        rangers = sorted(set(rangers_of(case.seed, case.vehicles)) - {LIAR, ACCOMPLICE}) or honest
        return [drift, {"name": "accomplice", "kind": "accuse", "vehicle": ACCOMPLICE, "names": rangers[:8], **at}]
    if case.condition == "relapse":
        gross = {"offset_m": [30.0, -30.0], "cov_scale": 0.01, "for_s": GROSS_S}
        then = {"start_s": START_S + GROSS_S}
        return [{"name": "gross", "kind": "lie", "vehicle": LIAR, **gross, **at}, {**drift, **then}]
    if case.condition == "stale":
        return [{"name": "stale", "kind": "lie", "vehicle": LIAR, "stale_s": 5.0, **at}]
    return []


def insiders_config(case: Case) -> SwarmConfig:
    rule = {  # two insiders at most: told f = 2 (the rule before: a quorum of two; default: f = 1, as shipped)
        "evidence": {"monitor": {"max_compromised": 2}},
        "quorum-only": {"monitor": {"rule": "quorum-only", "max_compromised": 1}},
        "off": {"monitor": {"enabled": False}},
        "default": {},  # the monitor as a new user has it: f = 1
    }
    return build_config(
        {
            "name": case.name,
            "world": {"vehicles": case.vehicles, "seed": case.seed, "sensor_truth": HONEST_WORLD},
            "sensors": HONEST_DATASHEET,
            "clock": {"duration_s": DURATION_S},
            "vehicle": rule.get(case.rule, {}),
            "faults": faults(case),
        }
    )


def plan(seeds: int, first_seed: int, conditions: str) -> list[RunSpec]:
    """Every case's run (the clean swarms always: they are what the others are compared with)."""
    return [
        RunSpec(case.name, case.group, case.seed, insiders_config(case).model_dump(mode="json"))
        for case in _cases_of(seeds, first_seed, conditions)
    ]


def conclude(rows: list[dict], folder: Path, **params: Any) -> list[str]:
    """experiment.json from the runs that completed; a line per condition."""
    table = summarize(completed(rows, _cases_of(**params), folder))
    write_experiment(folder, table)
    return [
        f"  {name:<24} honest RMSE / clean {row['honest_rmse_vs_clean_mean']} (max {row['honest_rmse_vs_clean_max']})"
        f"  honest distrusting honest {row['honest_distrusting_honest']}  distrust/trust events"
        f" {row['distrust_events']}/{row['trust_events']}  contradicted insiders {row['contradicted_insiders']}"
        f" honest {row['contradicted_honest']}"
        for name, row in table["conditions"].items()
    ]


def _cases_of(seeds: int, first_seed: int, conditions: str) -> list[Case]:
    chosen = tuple(dict.fromkeys(("clean", *(c.strip() for c in conditions.split(",") if c.strip()))))
    unknown = [c for c in chosen if c not in CONDITIONS]
    if unknown:
        raise ConfigError(f"unknown condition(s) {', '.join(unknown)}; known: {', '.join(CONDITIONS)}")
    return cases(list(range(first_seed, first_seed + seeds)), chosen)


@functools.cache
def rangers_of(seed: int, vehicles: int) -> tuple[int, ...]:
    """The vehicles the pure world of ``seed`` has ranging the liar after ``START_S``."""
    from bus.feed import SensorBatch
    from bus.topics import Topic
    from sim.world import World

    world = World(insiders_config(Case("clean", vehicles, "evidence", seed)))
    end_us, start_us = round(DURATION_S * 1e6), round(START_S * 1e6)
    out = world.advance(end_us)
    found = set()
    for vid in world.vehicle_ids():
        for topic, msg in SensorBatch(vid, 0, end_us, out.blocks(vid)).samples():
            if topic is Topic.RANGING and msg.target_id == LIAR and msg.stamp_us >= start_us:
                found.add(vid)
    return tuple(sorted(found))


def honest_rmse(run_dir: Path) -> float | None:
    """Position RMSE (m) of every vehicle but ``SCORED_OUT``, from START_S on."""
    metrics = load_run(run_dir).metrics
    if not metrics:
        return None
    keep = ~np.isin(metrics["vehicle"], SCORED_OUT) & (metrics["t_s"] >= START_S)
    return float(np.sqrt(np.mean(metrics["err_pos_m"][keep] ** 2))) if keep.any() else None


def trust_events(run_dir: Path) -> list[dict]:
    """The run's neighbour_distrusted, neighbour_trusted and accusation_contradicted events."""
    path = run_dir / "events.jsonl"
    kinds = ("neighbour_distrusted", "neighbour_trusted", "accusation_contradicted")
    lines = path.read_text().splitlines() if path.exists() else []
    return [e for e in map(json.loads, filter(str.strip, lines)) if e.get("event") in kinds]


def score(case: Case, run_dir: Path, clean_rmse: float | None) -> dict[str, Any]:
    """One run's row: honest RMSE against clean, and what the trust book did."""
    rmse = honest_rmse(run_dir)
    events = trust_events(run_dir)
    honest = lambda v: v not in case.insiders  # noqa: E731
    distrust = [e for e in events if e["event"] == "neighbour_distrusted"]
    contradicted = [e for e in events if e["event"] == "accusation_contradicted"]
    return {
        "ratio": rmse / clean_rmse if rmse is not None and clean_rmse else None,
        "honest_distrusting_honest": sum(1 for e in distrust if honest(e["vehicle"]) and honest(e["neighbour"])),
        "distrust_events": len(distrust),
        "trust_events": sum(1 for e in events if e["event"] == "neighbour_trusted"),
        "liar_trusted_again": sum(
            1 for e in events if e["event"] == "neighbour_trusted" and e["neighbour"] == LIAR and honest(e["vehicle"])
        ),
        "contradicted_insiders": sum(1 for e in contradicted if not honest(e["accuser"])),
        "contradicted_honest": sum(1 for e in contradicted if honest(e["accuser"]) and honest(e["vehicle"])),
    }


def summarize(runs: dict[Case, Path]) -> dict[str, Any]:
    """experiment.json: per condition, size and rule, the honest RMSE against clean (mean, max) and
    the trust book's events summed over the seeds."""
    clean = {(c.seed, c.vehicles): p for c, p in runs.items() if c.condition == "clean"}
    rows: dict[str, list[dict[str, Any]]] = {}
    for case, path in sorted(runs.items(), key=lambda item: (item[0].group, item[0].seed)):
        clean_path = clean.get((case.seed, case.vehicles))
        base = honest_rmse(clean_path) if clean_path is not None else None
        rows.setdefault(case.group, []).append(score(case, path, base))
    table: dict[str, Any] = {"seeds": sorted({c.seed for c in runs}), "duration_s": DURATION_S, "conditions": {}}
    for group, scored in rows.items():
        ratios = [r["ratio"] for r in scored if r["ratio"] is not None]
        table["conditions"][group] = {
            "runs": len(scored),
            "honest_rmse_vs_clean_mean": round(float(np.mean(ratios)), 4) if ratios else None,
            "honest_rmse_vs_clean_max": round(float(np.max(ratios)), 4) if ratios else None,
            **{k: sum(r[k] for r in scored) for k in scored[0] if k != "ratio"},
        }
    return table
