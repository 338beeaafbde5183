"""`swarm experiment liar`: a vehicle that lies to its neighbours, and whether the honest ones follow.

Eight vehicles in the honest world (``HONEST_WORLD`` with ``HONEST_DATASHEET``), 60 s, real processes
in lockstep. From ``LIE_START_S`` vehicle 3 (the liar) tells its neighbours, by profile:

- ``gross``: its position 30 m off (every single-fix gate rejects it);
- ``drift``: an offset growing 0.15 m/s (it passes every single-fix gate for seconds);
- ``overconfident``: its honest position with a covariance 100 times too small;
- ``spoofed``: nothing false on purpose: its own GNSS is spoofed (0.5 m/s), and it honestly
  broadcasts the estimate the spoofer drags. The spoofer's zone is centred on the liar's start pad,
  wide enough for the liar's whole path and no other vehicle's (``spoof_zone``).

Each profile flies with the neighbour monitor on and off (``vehicle.monitor.enabled``), next to the
clean swarm of the same seed; and the no-liar conditions (clean, GNSS jammed for six vehicles,
faults on the vehicle-to-vehicle links) fly with the monitor on to count false alarms; the same
jamming ending after ``JAMMING_ENDS_AFTER_S`` flies with the monitor on and off (with no liar there is
no verdict, so the difference is the neighbours' say on the GNSS resets as the receivers come back). Scored on
the honest vehicles (all but the liar) from ``LIE_START_S`` to the end. Detection: for each vehicle
that ranged the liar after the lie began (read off the pure world of the same seed), the time from
its first such ranging to its first ``neighbour_distrusted`` event about the liar (stamped with the
vehicle's own time: the SYSTEM_TIME before its STATUSTEXT), 0 when it distrusted the liar
on the word of others before it ranged it. A false alarm is any distrust
of an honest vehicle; those the liar itself raised are counted apart too (a spoofed vehicle that
distrusts the honest neighbours who could correct it hurts itself, not them).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bus.config import HONEST_DATASHEET, HONEST_WORLD, SwarmConfig, build_config
from bus.errors import ConfigError
from experiments.conclusions import completed, write_experiment
from groundstation.report.rundata import load_run
from launch.runspec import RunSpec

LIAR = 3
LIE_START_S = 10.0
DURATION_S = 60.0
VEHICLES = 8
LIES: dict[str, dict[str, Any]] = {
    "gross": {"offset_m": [30.0, -30.0]},
    "drift": {"drift_mps": 0.15, "heading_deg": 45.0},
    "overconfident": {"cov_scale": 0.01},
}
V2V_LINK_FAULTS = [
    {"kind": "delay", "dst": "v*", "topic": "mavlink", "delay_s": 0.05, "jitter_s": 0.02},
    {"kind": "loss", "dst": "v*", "topic": "mavlink", "percent": 20.0, "burst": 4.0},
    {"kind": "duplicate", "dst": "v*", "topic": "mavlink", "percent": 10.0},
    {"kind": "reorder", "dst": "v*", "topic": "mavlink", "percent": 10.0, "gap_s": 0.05},
]
PROFILES = ("gross", "drift", "overconfident", "spoofed")
CONTROLS = ("clean", "jamming", "jamming-ends", "links")
JAMMING_ENDS_AFTER_S = 20.0


@dataclass(frozen=True)
class Case:
    condition: str  # a lie profile or a control
    defence: bool
    seed: int
    silenced_after_s: float | None = None  # the liar's V2V cut this long after the lie began (monitor off)

    @property
    def name(self) -> str:
        return f"{self.group}-seed{self.seed}"

    @property
    def group(self) -> str:
        """The row of experiment.json the case belongs to."""
        if self.silenced_after_s is not None:
            return f"{self.condition}-silenced-{self.silenced_after_s:g}s"
        return f"{self.condition}-{'defended' if self.defence else 'open'}"


def cases(seeds: list[int], profiles: tuple[str, ...] = PROFILES, silenced: tuple[float, ...] = ()) -> list[Case]:
    """Every run of the experiment: the controls defended (clean also open: the monitor's own cost),
    each profile defended and open, and each profile silenced after each of ``silenced`` (s): an
    oracle that knows the liar and cuts it off that long after the lie began, the best a detector
    that fast could do."""
    out = []
    for seed in seeds:
        out += [Case("clean", True, seed), Case("clean", False, seed), Case("jamming", True, seed)]
        out += [Case("jamming-ends", True, seed), Case("jamming-ends", False, seed)]
        out += [Case("links", True, seed)]
        out += [Case(p, d, seed) for p in profiles for d in (True, False)]
        out += [Case(p, False, seed, after) for p in profiles for after in silenced]
    return out


def liar_config(case: Case) -> SwarmConfig:
    faults: list[dict] = []
    if case.condition in LIES:
        faults.append({"name": "liar", "kind": "lie", "vehicle": LIAR, "start_s": LIE_START_S, **LIES[case.condition]})
    elif case.condition == "spoofed":
        center_m, radius_m = spoof_zone(case.seed)
        faults.append(
            {
                "name": "spoofer",
                "kind": "spoof-gnss",
                "center_m": list(center_m),
                "radius_m": radius_m,
                "drift_mps": 0.5,
                "heading_deg": 45.0,
                "start_s": LIE_START_S,
            }
        )
    elif case.condition in ("jamming", "jamming-ends"):
        length = {"for_s": JAMMING_ENDS_AFTER_S} if case.condition == "jamming-ends" else {}
        faults += [
            {"name": f"jam-v{v}", "kind": "blackout", "vehicle": v, "sensor": "gnss", "start_s": LIE_START_S, **length}
            for v in range(1, 7)
        ]
    elif case.condition == "links":
        faults += [{"name": f"link-{k}", **f, "start_s": LIE_START_S} for k, f in enumerate(V2V_LINK_FAULTS)]
    if case.silenced_after_s is not None:
        start_s = LIE_START_S + case.silenced_after_s
        faults.append(
            {"name": "oracle", "kind": "loss", "src": f"v{LIAR}", "dst": "v*", "percent": 100.0, "start_s": start_s}
        )
    return build_config(
        {
            "name": case.name,
            "world": {"vehicles": VEHICLES, "seed": case.seed, "sensor_truth": HONEST_WORLD},
            "sensors": HONEST_DATASHEET,
            "clock": {"duration_s": DURATION_S},
            "vehicle": {"monitor": {"enabled": case.defence}},
            "faults": faults,
        }
    )


@functools.cache
def spoof_zone(seed: int) -> tuple[tuple[float, float], float]:
    """The spoofer's zone for the ``spoofed`` profile: centred on the liar's start pad (m), its radius
    (m) halfway between the farthest the liar gets from the pad and the nearest any other vehicle
    comes, over the whole run of the pure world of the same seed: only the liar is ever spoofed."""
    from sim.world import World

    world = World(_world_config(seed))
    liar = world.vehicle_ids().index(LIAR)
    center = np.round(world.poses[liar][:2], 1)
    truth = np.stack(world.advance(round(DURATION_S * 1e6)).truth)  # (k, N, 5)
    distance = np.hypot(*(truth[:, :, :2] - center).transpose(2, 0, 1))  # (k, N)
    liar_reach, others_nearest = distance[:, liar].max(), np.delete(distance, liar, axis=1).min()
    if not liar_reach < others_nearest:
        raise ConfigError(f"seed {seed}: no spoofer zone holds the liar's path and no other vehicle's")
    return (float(center[0]), float(center[1])), round(float(liar_reach + others_nearest) / 2.0, 1)


def _world_config(seed: int) -> SwarmConfig:
    """The world every case of ``seed`` flies (the faults aside)."""
    return liar_config(Case("clean", True, seed))


def plan(seeds: int, first_seed: int, profiles: str, silenced: str) -> list[RunSpec]:
    """Every case's run, named as the case (one-line ConfigError for unknown profiles or delays)."""
    return [
        RunSpec(case.name, case.group, case.seed, liar_config(case).model_dump(mode="json"))
        for case in _cases_of(seeds, first_seed, profiles, silenced)
    ]


def conclude(rows: list[dict], folder: Path, **params: Any) -> list[str]:
    """experiment.json from the runs that completed; a line per condition."""
    table = summarize(completed(rows, _cases_of(**params), folder))
    write_experiment(folder, table)
    return [
        f"  {name:<26} honest RMSE / clean {row['honest_rmse_vs_clean_mean']} (max {row['honest_rmse_vs_clean_max']})"
        f"  liar distrusted by {row['rangers_that_distrusted_the_liar']}"
        f" (median {row['detection_s_median']} s, max {row['detection_s_max']} s)  false alarms {row['false_alarms']}"
        for name, row in table["conditions"].items()
    ]


def _cases_of(seeds: int, first_seed: int, profiles: str, silenced: str) -> list[Case]:
    chosen = tuple(p.strip() for p in profiles.split(",") if p.strip())
    unknown = [p for p in chosen if p not in PROFILES]
    if unknown or not chosen:
        raise ConfigError(f"unknown profile(s) {', '.join(unknown) or '(none given)'}; known: {', '.join(PROFILES)}")
    return cases(list(range(first_seed, first_seed + seeds)), chosen, _delays(silenced))


def _delays(text: str) -> tuple[float, ...]:
    """--silenced's delays (s), each from 0 to the lie's length; a one-line ConfigError otherwise."""
    delays = []
    for item in (t.strip() for t in text.split(",") if t.strip()):
        try:
            delay = float(item)
        except ValueError:
            raise ConfigError(f"--silenced: {item!r} is not a number of seconds") from None
        if not 0.0 <= delay <= DURATION_S - LIE_START_S:
            raise ConfigError(f"--silenced: {item} s is outside 0 to {DURATION_S - LIE_START_S:g} s (the lie's length)")
        delays.append(delay)
    return tuple(dict.fromkeys(delays))


def honest_rmse(run_dir: Path) -> float | None:
    """Position RMSE (m) of every vehicle but the liar, from LIE_START_S on."""
    return _rmse_from_lie(run_dir, liar=False)


def liar_rmse(run_dir: Path) -> float | None:
    """Position RMSE (m) of the liar's own estimate (its MAVLink stays honest), from LIE_START_S on."""
    return _rmse_from_lie(run_dir, liar=True)


def _rmse_from_lie(run_dir: Path, *, liar: bool) -> float | None:
    metrics = load_run(run_dir).metrics
    if not metrics:
        return None
    keep = ((metrics["vehicle"] == LIAR) == liar) & (metrics["t_s"] >= LIE_START_S)
    return float(np.sqrt(np.mean(metrics["err_pos_m"][keep] ** 2))) if keep.any() else None


def distrust_events(run_dir: Path) -> list[dict]:
    """The run's neighbour_distrusted events."""
    path = run_dir / "events.jsonl"
    if not path.exists():
        return []
    events = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return [e for e in events if e.get("event") == "neighbour_distrusted"]


def rangers_of_liar(seed: int) -> dict[int, float]:
    """The vehicles the pure world has ranging the liar after the lie began (the same world as the
    run), with the sim time (s) of the first such ranging: detection is counted from there."""
    from bus.feed import SensorBatch
    from bus.topics import Topic
    from sim.world import World

    world = World(_world_config(seed))
    out = world.advance(round(DURATION_S * 1e6))
    start = round(LIE_START_S * 1e6)
    rangers: dict[int, float] = {}
    for vid in world.vehicle_ids():
        for topic, msg in SensorBatch(vid, 0, round(DURATION_S * 1e6), out.blocks(vid)).samples():
            if topic is Topic.RANGING and msg.target_id == LIAR and msg.stamp_us >= start and vid not in rangers:
                rangers[vid] = msg.stamp_us / 1e6
    return rangers


def summarize(runs: dict[Case, Path]) -> dict[str, Any]:
    """experiment.json: per condition and defence, the honest RMSE against the clean run of the same
    seed, detections of the liar and false alarms."""
    seeds = sorted({c.seed for c in runs})
    clean = {s: honest_rmse(runs[Case("clean", False, s)]) for s in seeds if Case("clean", False, s) in runs}
    rangers = {s: rangers_of_liar(s) for s in seeds}
    table: dict[str, Any] = {"seeds": seeds, "liar": LIAR, "lie_start_s": LIE_START_S, "conditions": {}}
    groups = {c.group: c for c in runs}
    order = sorted(groups, key=lambda g: (groups[g].condition not in CONTROLS, groups[g].condition, _rank(groups[g])))
    for key in order:
        condition = groups[key].condition
        rows = [(c, p) for c, p in runs.items() if c.group == key]
        ratios, delays, detected, falsely, by_liar, own, before = [], [], 0, 0, 0, [], 0
        for case, path in rows:
            rmse = honest_rmse(path)
            if rmse is not None and clean.get(case.seed):
                ratios.append(rmse / clean[case.seed])
            own += [r for r in [liar_rmse(path)] if r is not None]
            events = distrust_events(path)
            liar_events = {e["vehicle"]: e["t_s"] for e in reversed(events) if e.get("neighbour") == LIAR}
            lie = condition in PROFILES
            false_alarms = [e for e in events if not lie or e.get("neighbour") != LIAR]
            falsely += len(false_alarms)
            by_liar += sum(1 for e in false_alarms if e.get("vehicle") == LIAR)
            if lie:
                expected = {v: t for v, t in rangers[case.seed].items() if v != LIAR}
                detected += sum(1 for v in expected if v in liar_events)
                delays += [max(0.0, liar_events[v] - t) for v, t in expected.items() if v in liar_events]
                before += sum(1 for v, t in expected.items() if liar_events.get(v, math.inf) < t)
                delays += [math.inf for v in expected if v not in liar_events]
        finite = [d for d in delays if math.isfinite(d)]
        table["conditions"][key] = {
            "runs": len(rows),
            "honest_rmse_vs_clean_mean": round(float(np.mean(ratios)), 4) if ratios else None,
            "honest_rmse_vs_clean_max": round(float(np.max(ratios)), 4) if ratios else None,
            "rangers_that_distrusted_the_liar": f"{len(finite)} of {len(delays)}" if delays else None,
            "distrusted_before_ranging_it": before,  # on the others' word: detection 0
            "detection_s_median": round(float(np.median(finite)), 2) if finite else None,
            "detection_s_max": round(float(np.max(finite)), 2) if finite else None,
            "false_alarms": falsely,
            "false_alarms_by_the_liar": by_liar,  # the liar distrusting honest neighbours (its own loss)
            "liar_own_rmse_m_mean": round(float(np.mean(own)), 3) if own else None,  # its honest estimate's error
        }
    return table


def _rank(case: Case) -> tuple[int, float]:
    """A condition's rows in order: open, defended, then silenced soonest first."""
    if case.silenced_after_s is not None:
        return 2, case.silenced_after_s
    return (1 if case.defence else 0), 0.0
