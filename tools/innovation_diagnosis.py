"""Can a vehicle see its own over-confidence in its innovations? On data set 6, each fold of the two-fold
cross-validation, known-map alone (no neighbours: what one vehicle sees), per robot: the mean NIS of
its landmark sightings (2 dof: 2 for an honest filter), its block ANEES (docs/real-data.md), and how
the 30 s blocks' mean NIS follows their mean NEES (correlation, and the NIS in the blocks whose NEES
is above 6). docs/decisions/mrclam.md has the table.

    python tools/innovation_diagnosis.py DATASET [--folds 1,2] [--robots 1,2,3,4,5]
"""

from __future__ import annotations

import argparse

import numpy as np

import vehicle.estimators.known_map as known_map
from bus.consistency import BLOCK_S, consistency
from experiments.harness import replay_in_memory
from launch.replay_setup import ReplayChoice, replay_config
from sim.mrclam import load_mrclam
from vehicle.estimators import get_estimator


def one_robot(dataset: str, data, fold: int, robot: int) -> dict:
    """The robot's NEES rows and its landmark NIS, replayed alone (known-map: its own sightings only)."""
    nis: list[tuple[float, float]] = []
    tally = known_map.tally_nis

    def recording(s, kind, result, dof):
        if result.accepted:
            nis.append((s.time_us * 1e-6, result.nis))
        tally(s, kind, result, dof)

    known_map.tally_nis = recording
    try:
        config = replay_config(ReplayChoice(dataset, estimator="known-map", fold=fold), name="diagnosis")
        estimator = {robot: get_estimator(config.for_vehicle(), robot)}
        rows = replay_in_memory(config, data, every_us=200_000, estimators=estimator)[robot]
    finally:
        known_map.tally_nis = tally
    t, nees = rows[:, 0] * 1e-6, rows[:, 2]
    nis_t, nis_v = np.array(nis).T if nis else (np.zeros(0), np.zeros(0))
    block_nees, block_nis = [], []
    for start in np.arange(t[0], t[-1], BLOCK_S):
        inside, seen = (t >= start) & (t < start + BLOCK_S), (nis_t >= start) & (nis_t < start + BLOCK_S)
        if seen.sum() >= 5:
            block_nees.append(nees[inside].mean())
            block_nis.append(nis_v[seen].mean())
    block_nees, block_nis = np.array(block_nees), np.array(block_nis)
    high = block_nees > 6.0
    return {
        "mean_landmark_nis": float(nis_v.mean()),
        "block_anees": consistency(t, nees).block_anees,
        "correlation": float(np.corrcoef(block_nees, block_nis)[0, 1]),
        "nis_where_nees_above_6": float(block_nis[high].mean()) if high.any() else float("nan"),
        "nis_elsewhere": float(block_nis[~high].mean()),
        "blocks_nees_above_6": int(high.sum()),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dataset")
    parser.add_argument("--folds", default="1,2")
    parser.add_argument("--robots", default="1,2,3,4,5")
    args = parser.parse_args()
    data = load_mrclam(args.dataset)
    print(
        "| fold | robot | mean landmark NIS (2 dof) | block ANEES | corr(block NIS, block NEES) "
        "| block NIS where NEES > 6 / elsewhere |"
    )
    print("|---|---|---|---|---|---|")
    for fold in (int(f) for f in args.folds.split(",")):
        for robot in (int(r) for r in args.robots.split(",")):
            d = one_robot(args.dataset, data, fold, robot)
            print(
                f"| {fold} | {robot} | {d['mean_landmark_nis']:.2f} | {d['block_anees']:.2f} | {d['correlation']:+.2f} "
                f"| {d['nis_where_nees_above_6']:.2f} ({d['blocks_nees_above_6']} blocks) / {d['nis_elsewhere']:.2f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
