"""Why the centralized reference wins or loses against split CI on the cooperative experiment's worlds
(docs/decisions/centralized-reference.md): each seed flown by split CI through the real vehicle
nodes on the in-memory bus and by the centralized reference beside the world, both scored on the
jammed vehicles over the jam; the reference's error split into the swarm's common mode (centroid,
mean heading) and the relative part, each against what it claims (experiments.swarm_modes), by phase.

    python tools/reference_diagnosis.py --seeds 1,2,3 [--world ideal]
        [--truth odom_scale_sigma=0 ...] [--datasheet odom_scale_prior_sigma=0.005 ...] [--no-split]

``--truth`` overrides the world's sensor truth (bus.sensor_config.SensorTruth), ``--datasheet`` what
the filters are told (bus.sensor_config.SensorSpec), both on top of the experiment's own.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from bus.config import SwarmConfig, build_config
from bus.errors import ConfigError
from experiments.centralized_reference import run_centralized
from experiments.cooperative import Setup, cooperative_config
from experiments.harness import swarm_in_memory
from experiments.swarm_modes import SwarmModes

PHASES_S = ((0.0, 20.0), (20.0, 60.0), (60.0, 100.0), (100.0, 140.0))  # GNSS on, then the jam in thirds


def _overrides(pairs: list[str]) -> dict[str, float]:
    out = {}
    for pair in pairs:
        key, _, value = pair.partition("=")
        try:
            out[key] = float(value)
        except ValueError:
            raise SystemExit(f"reference_diagnosis: {pair!r} is not key=number") from None
    return out


def diagnosis_config(seed: int, world: str, truth: dict[str, float], datasheet: dict[str, float]) -> SwarmConfig:
    """The cooperative experiment's swarm (split CI, the default) on ``seed`` with these overrides."""
    data = cooperative_config("ci-ekf", seed, Setup(world=world)).model_dump(mode="json")
    data["world"]["sensor_truth"].update(truth)
    data["sensors"].update(datasheet)
    return build_config(data)


def jammed_score(tracks: dict[int, dict[str, np.ndarray]], setup: Setup) -> tuple[float, float]:
    """RMSE (m) and ANEES of the jammed vehicles over the jam."""
    errors, nees = [], []
    for vid in setup.jammed_ids:
        over_jam = tracks[vid]["t_s"] >= setup.jam_start_s
        errors.append(tracks[vid]["error_m"][over_jam])
        nees.append(tracks[vid]["nees"][over_jam])
    return float(np.sqrt(np.mean(np.concatenate(errors) ** 2))), float(np.concatenate(nees).mean())


def phase_lines(modes: list[tuple[float, SwarmModes]]) -> list[str]:
    """One line per phase: the mean NEES of each part and the centroid's error against its claim."""
    lines = []
    for start, end in PHASES_S:
        held = [m for t, m in modes if start <= t < end]
        if not held:
            continue
        mean = {key: float(np.mean([getattr(m, key) for m in held])) for key in vars(held[0])}
        lines.append(
            f"    {start:3.0f}-{end:3.0f} s  centroid NEES {mean['centroid_nees']:5.2f} (2 dof), "
            f"{mean['centroid_error_m']:.3f} m claimed {mean['centroid_sigma_m']:.3f} m | "
            f"mean heading NEES {mean['heading_nees']:5.2f} (1 dof) | "
            f"relative NEES {mean['relative_nees']:5.1f} ({mean['relative_dof']:.0f} dof)"
        )
    return lines


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="1,2,3")
    parser.add_argument("--world", choices=("honest", "ideal"), default="honest")
    parser.add_argument("--truth", nargs="*", default=[], metavar="KEY=VALUE")
    parser.add_argument("--datasheet", nargs="*", default=[], metavar="KEY=VALUE")
    parser.add_argument("--no-split", action="store_true", help="fly the centralized reference alone")
    args = parser.parse_args(argv)
    setup = Setup(world=args.world)
    truth, datasheet = _overrides(args.truth), _overrides(args.datasheet)
    totals: dict[str, list[np.ndarray]] = {"split CI": [], "centralized": []}
    for seed in (int(s) for s in args.seeds.split(",")):
        try:
            config = diagnosis_config(seed, args.world, truth, datasheet)
        except ConfigError as exc:
            print(f"reference_diagnosis: {exc}", file=sys.stderr)
            return 2
        modes: list[tuple[float, SwarmModes]] = []
        scores = {"centralized": jammed_score(run_centralized(config, modes=modes), setup)}
        if not args.no_split:
            scores["split CI"] = jammed_score(swarm_in_memory(config), setup)
        print(f"seed {seed}: " + " | ".join(f"{k} {r:.3f} m ANEES {a:.2f}" for k, (r, a) in scores.items()))
        print("\n".join(phase_lines(modes)), flush=True)
        for key, (rmse, _) in scores.items():
            totals[key].append(np.array(rmse))
    for key, rmses in totals.items():
        if rmses:
            print(f"{key}: RMSE over the seeds (root mean square of theirs) {np.sqrt(np.mean(np.square(rmses))):.3f} m")
    return 0


if __name__ == "__main__":
    sys.exit(main())
