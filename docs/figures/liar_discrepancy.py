"""How far a neighbour's broadcast is off where the ranging puts it, honest or lying: the numbers behind
"what is not reached" in docs/liars.md.

Each neighbour fix the monitor judges says, in the world frame, how far the neighbour seems from its
broadcast position: delta = -J^-1 y (y the fix's innovation, J = d h / d(own position)), read back
from the monitor's record as delta = -G^-1 w (w the whitened innovation, G the whitened J). Runs the
liar experiment's swarm (eight vehicles of the honest world, 60 s) in one process
(experiments.harness.swarm_in_memory), clean and under the slow drift, with the monitor on, and
compares 5 s means per observer and neighbour: over all honest pairs of the clean runs, against the
liar's as its rangers see it from the lie's start.

    python docs/figures/liar_discrepancy.py docs/data/liar-discrepancy.json [--seeds 1,2,3]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from bus.config import build_config
from experiments.harness import swarm_in_memory
from experiments.liar import LIAR, LIE_START_S, Case, liar_config
from vehicle.estimators.trust import NeighbourTrust
from vehicle.trust.neighbour_fixes import Fix

WINDOW_S = 5.0
MIN_FIXES = 10  # a window's mean counts with at least this many fixes


def world_offset(fix: Fix) -> tuple[float, float] | None:
    """delta = -G^-1 w (m, world frame) of one recorded fix; None where G is singular."""
    G = np.array(fix.shift).reshape(2, 2)
    if abs(np.linalg.det(G)) < 1e-12:
        return None
    d = -np.linalg.solve(G, np.array(fix.whitened))
    return float(d[0]), float(d[1])


def recorded_fixes(condition: str, seed: int) -> dict[tuple[int, int], dict[int, tuple[float, float]]]:
    """(observer, neighbour) -> {stamp us: world offset} of every fix judged in one run (a fusion
    horizon replay judges a fix again: the last judgement counts)."""
    out: dict[tuple[int, int], dict[int, tuple[float, float]]] = {}
    nodes: list = []
    judge = NeighbourTrust.judge

    def recording(self, f, neighbour, fix, result):
        believed = judge(self, f, neighbour, fix, result)
        observer = next(n.vehicle_id for n in nodes if n.estimator is f)
        record = f.state.neighbours.records.get(neighbour)
        if record is not None and record.fixes and (offset := world_offset(record.fixes[-1])) is not None:
            out.setdefault((observer, neighbour), {})[record.fixes[-1].stamp_us] = offset
        return believed

    NeighbourTrust.judge = recording
    try:
        swarm_in_memory(build_config(liar_config(Case(condition, True, seed))), nodes_out=nodes)
    finally:
        NeighbourTrust.judge = judge
    return out


def window_means(fixes: dict[int, tuple[float, float]], from_s: float) -> list[tuple[float, float]]:
    """(end s, |mean offset| m) of each 5 s window ending every second from ``from_s + 5``."""
    stamps = np.array(sorted(fixes)) * 1e-6
    offsets = np.array([fixes[k] for k in sorted(fixes)])
    out = []
    for end in np.arange(from_s + WINDOW_S, 60.0 + 1e-9, 1.0):
        inside = (stamps > end - WINDOW_S) & (stamps <= end)
        if inside.sum() >= MIN_FIXES:
            out.append((float(end), float(np.hypot(*offsets[inside].mean(axis=0)))))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=Path)
    parser.add_argument("--seeds", default="1,2,3")
    args = parser.parse_args()
    seeds, out_path = [int(s) for s in args.seeds.split(",")], args.out
    honest: list[float] = []
    liar: dict[str, list] = {}
    for seed in seeds:
        for fixes in recorded_fixes("clean", seed).values():
            honest += [m for _, m in window_means(fixes, LIE_START_S)]
        for (observer, neighbour), fixes in recorded_fixes("drift", seed).items():
            if neighbour == LIAR:
                liar[f"seed {seed}: v{observer} sees v{neighbour}"] = window_means(fixes, LIE_START_S)
    top = max(honest)
    summary = {
        "honest_windows": len(honest),
        "honest_median_m": round(float(np.median(honest)), 2),
        "honest_p99_m": round(float(np.percentile(honest, 99)), 2),
        "honest_max_m": round(top, 2),
        "liar_after_5s_m": {
            k: next((round(m, 2) for end, m in w if end == LIE_START_S + WINDOW_S), None) for k, w in liar.items()
        },
        "liar_above_honest_max_after_s": {
            k: next((round(end - LIE_START_S, 1) for end, m in w if m > top), None) for k, w in liar.items()
        },
    }
    out_path.write_text(json.dumps(summary, indent=2, sort_keys=True) + "\n")
    print(json.dumps(summary, indent=2, sort_keys=True))


if __name__ == "__main__":
    main()
