"""The linear study of cross-covariance factors (experiments.correlation_study), as the table of
docs/decisions/cross-covariance.md: per ranging graph, regime and method, the expected NEES (3 for an
honest filter; mean and range over the vehicles) and the RMS position error.

    python tools/correlation_study.py [--relative-var 0.05,0.5,5] [--losses 0.001,0.01,0.05] [--seeds 10]

Then Kia et al.'s algorithm under lost broadcasts (the second table of the page): per graph and loss,
how many of the seeds' runs broke down (a vehicle's books no longer a possible joint covariance) and
when, and the expected NEES of the runs that did not.
"""

from __future__ import annotations

import argparse

import numpy as np

from experiments.correlation_study import METHODS, Regime, study

GRAPHS = {
    "pair": (2, [(0, 1)]),
    "chain of 3": (3, [(0, 1), (1, 2)]),
    "triangle": (3, [(0, 1), (1, 2), (0, 2)]),
    "complete 5": (5, [(a, b) for a in range(5) for b in range(a + 1, 5)]),
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--relative-var", default="0.05,0.5,5", help="relative measurement variances (m^2), comma-separated"
    )
    parser.add_argument("--losses", default="0.001,0.01,0.05", help="kia: broadcast loss probabilities")
    parser.add_argument("--seeds", type=int, default=10, help="kia: runs per loss (seeds of the losses)")
    args = parser.parse_args()
    method_table(args.relative_var)
    loss_table([float(v) for v in args.losses.split(",")], args.seeds)


def method_table(relative_vars: str) -> None:
    print("| graph | relative var m^2 | method | expected NEES (mean, range) | RMS position m |")
    print("|---|---|---|---|---|")
    for relative_var in (float(v) for v in relative_vars.split(",")):
        for graph, (n, pairs) in GRAPHS.items():
            for method in METHODS:
                out = study(n, pairs, method, Regime(relative_var=relative_var))
                nees = out.expected_nees
                print(
                    f"| {graph} | {relative_var:g} | {method} | {nees.mean():.2f} ({nees.min():.2f}-{nees.max():.2f}) "
                    f"| {out.rms_position_m:.3f} |"
                )


def loss_table(losses: list[float], seeds: int) -> None:
    print()
    print("| graph | broadcast loss | runs broken down | epochs at which | expected NEES of the others |")
    print("|---|---|---|---|---|")
    for graph, (n, pairs) in GRAPHS.items():
        if n < 3:
            continue
        for loss in losses:
            runs = [study(n, pairs, "kia", Regime(loss=loss, seed=seed)) for seed in range(seeds)]
            broken = sorted(r.broke_at for r in runs if r.broke_at is not None)
            whole = [r.expected_nees for r in runs if r.broke_at is None]
            nees = f"{np.mean(whole):.2f} ({np.min(whole):.2f}-{np.max(whole):.2f})" if whole else "-"
            print(f"| {graph} | {loss:g} | {len(broken)} of {seeds} | {', '.join(map(str, broken)) or '-'} | {nees} |")


if __name__ == "__main__":
    main()
