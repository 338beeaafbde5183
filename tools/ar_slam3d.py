"""The AR-EKF-SLAM paper's 3-D experiment on its back end (experiments.ar_slam3d): one flight of
``--frames`` frames estimated with the adaptive range, a fixed 25 m range and (``--full``) no range,
the paper's figures 7 (time per frame) and 8 (the track and its error), and the position NEES over
``--seeds`` shorter flights at checkpoints. Writes ``--out``/ar-slam3d-experiment.json and the two
figures (docs/ar-slam.md shows them).

    python tools/ar_slam3d.py [--frames 1600] [--seeds 30] [--full] [--out docs]
        [--baseline-frames 10] [--min-parallax 2] [--entry second] [--tag NAME]

``--tag``: write ar-slam3d-NAME.json and no figures (a variant beside the default run).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from bus.statistics import chi2_band
from experiments.ar_slam3d import Track, fly

CHECKPOINTS = (99, 199, 299)  # frames of the Monte Carlo flights (300 frames, 150 m)


def summary(track: Track) -> dict:
    error = np.linalg.norm(track.estimate - track.truth, axis=1)
    return {
        "rmse_m": round(float(np.sqrt(np.mean(error**2))), 3),
        "final_error_m": round(float(error[-1]), 3),
        "distance_m": round(float(np.sum(np.linalg.norm(np.diff(track.truth, axis=0), axis=1))), 1),
        "position_anees": round(float(track.position_nees().mean()), 2),
        "frame_ms_p50": round(float(np.median(track.frame_ms)), 2),
        "frame_ms_p99": round(float(np.percentile(track.frame_ms, 99)), 2),
        "landmarks_max": int(track.landmarks.max()),
        "radius_m": [round(float(track.radius_m.min()), 1), round(float(track.radius_m.max()), 1)],
    }


def figure_time(tracks: dict[str, Track], path: Path) -> None:
    fig = Figure(figsize=(9, 6), layout="constrained")
    top, middle, bottom = fig.subplots(3, 1, sharex=True)
    for name, track in tracks.items():
        frames = np.arange(1, len(track.frame_ms) + 1)
        top.plot(frames, track.frame_ms, lw=0.6, label=name)
        middle.plot(frames, track.landmarks, lw=0.8, label=name)
        bottom.plot(frames, track.radius_m, lw=0.8, label=name)
    top.set_ylabel("time per frame [ms]")
    top.set_yscale("log")
    top.legend()
    middle.set_ylabel("landmarks in the state")
    bottom.set_ylabel("range R [m]")
    bottom.set_ylim(0, 40)
    bottom.set_xlabel("frame")
    fig.suptitle("3-D AR-EKF-SLAM: per-frame cost, adaptive against fixed range (paper's fig. 7)")
    fig.savefig(path, dpi=110)


def figure_track(tracks: dict[str, Track], path: Path) -> None:
    fig = Figure(figsize=(9, 7), layout="constrained")
    plan, height, error = fig.subplots(3, 1)
    truth = next(iter(tracks.values())).truth
    plan.plot(truth[:, 0], truth[:, 1], "k", lw=1.5, label="truth")
    height.plot(truth[:, 0], truth[:, 2], "k", lw=1.5, label="truth")
    for name, track in tracks.items():
        plan.plot(track.estimate[:, 0], track.estimate[:, 1], lw=0.9, label=name)
        height.plot(track.estimate[:, 0], track.estimate[:, 2], lw=0.9, label=name)
        e = np.linalg.norm(track.estimate - track.truth, axis=1)
        error.plot(track.t_s, e, lw=0.9, label=f"{name} error")
        error.plot(
            track.t_s,
            np.sqrt(np.trace(track.covariance, axis1=1, axis2=2)),
            lw=0.6,
            ls="--",
            label=f"{name} claimed 1-sigma",
        )
    plan.set_ylabel("y [m]")
    plan.legend(fontsize=8)
    height.set_xlabel("x [m]")
    height.set_ylabel("altitude [m]")
    error.set_xlabel("time [s]")
    error.set_ylabel("position error [m]")
    error.legend(fontsize=7, ncol=2)
    fig.suptitle("3-D AR-EKF-SLAM: true against estimated track (paper's fig. 8)")
    fig.savefig(path, dpi=110)


def monte_carlo(seeds: int, two_frames: dict) -> dict:
    """Position (3 dof) and vehicle (position and velocity, 6 dof) NEES at the checkpoints of ``seeds``
    300-frame flights, each range and association, and the landmarks' mean NEES where they are
    identified."""
    low, high = chi2_band(3, runs=seeds)
    low6, high6 = chi2_band(6, runs=seeds)
    cases = {}
    for identified in (True, False):
        for mode in ("adaptive", "fixed-25"):
            tracks = [fly(s, 300, mode, identified=identified, **two_frames) for s in range(seeds)]
            position = _at_checkpoints(np.array([t.position_nees() for t in tracks]))
            vehicle = _at_checkpoints(np.array([t.vehicle_nees() for t in tracks]))
            key = f"{mode}, {'identified' if identified else 'nn association'}"
            cases[key] = {
                "checkpoint_position_anees": position,
                "inside": [low <= m <= high for m in position],
                "checkpoint_vehicle_anees": vehicle,
                "vehicle_inside": [low6 <= m <= high6 for m in vehicle],
            }
            if identified:  # the landmarks' NEES needs their true identities
                cases[key]["checkpoint_landmark_mean_nees"] = _at_checkpoints(
                    np.array([t.landmark_nees for t in tracks])
                )
            print(key, cases[key], flush=True)
    return {
        "seeds": seeds,
        "checkpoints_frame": [c + 1 for c in CHECKPOINTS],
        "band_95": [round(low, 2), round(high, 2)],
        "band_95_vehicle_6dof": [round(low6, 2), round(high6, 2)],
        "cases": cases,
    }


def _at_checkpoints(nees: np.ndarray) -> list[float]:
    """Mean over the flights (rows) of ``nees`` (flights, frames) at each checkpoint (NaNs left out)."""
    return [round(float(np.nanmean(nees[:, c])), 2) for c in CHECKPOINTS]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=1600)
    parser.add_argument("--seeds", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--full", action="store_true", help="also full EKF-SLAM (no range: slow)")
    parser.add_argument("--out", type=Path, default=Path("docs"))
    parser.add_argument("--baseline-frames", type=int, default=10, help="triangulate with the frame this many before")
    parser.add_argument("--min-parallax", type=float, default=2.0, help="degrees")
    parser.add_argument("--entry", default="second", choices=("first", "second"), help="how points enter the map")
    parser.add_argument("--tag", default="", help="a variant: its own JSON, no figures")
    args = parser.parse_args()
    two_frames = {"baseline_frames": args.baseline_frames, "min_parallax_deg": args.min_parallax, "entry": args.entry}
    modes = ("adaptive", "fixed-25") + (("full",) if args.full else ())
    tracks = {mode: fly(args.seed, args.frames, mode, **two_frames) for mode in modes}
    result: dict = {
        "frames": args.frames,
        "seed": args.seed,
        **two_frames,
        "flight": {m: summary(t) for m, t in tracks.items()},
    }
    print(json.dumps(result["flight"], indent=1), flush=True)
    result["monte_carlo"] = monte_carlo(args.seeds, two_frames)
    (args.out / "data").mkdir(parents=True, exist_ok=True)
    name = f"ar-slam3d-{args.tag}.json" if args.tag else "ar-slam3d-experiment.json"
    (args.out / "data" / name).write_text(json.dumps(result, indent=2) + "\n")
    if not args.tag:
        figure_time(tracks, args.out / "img" / "ar-slam3d-frame-time.png")
        figure_track(tracks, args.out / "img" / "ar-slam3d-track.png")


if __name__ == "__main__":
    main()
