"""The linear study of cross-covariance factors (experiments.correlation_study), as the table of
docs/decisions/cross-covariance.md: per ranging graph, regime and method, the expected NEES (3 for an
honest filter; mean and range over the vehicles) and the RMS position error.

    python tools/correlation_study.py [--relative-var 0.05,0.5,5]
"""

from __future__ import annotations

import argparse

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
    args = parser.parse_args()
    print("| graph | relative var m^2 | method | expected NEES (mean, range) | RMS position m |")
    print("|---|---|---|---|---|")
    for relative_var in (float(v) for v in args.relative_var.split(",")):
        for graph, (n, pairs) in GRAPHS.items():
            for method in METHODS:
                out = study(n, pairs, method, Regime(relative_var=relative_var))
                nees = out.expected_nees
                print(
                    f"| {graph} | {relative_var:g} | {method} | {nees.mean():.2f} ({nees.min():.2f}-{nees.max():.2f}) "
                    f"| {out.rms_position_m:.3f} |"
                )


if __name__ == "__main__":
    main()
