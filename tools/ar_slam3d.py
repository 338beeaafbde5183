"""The AR-EKF-SLAM paper's 3-D experiment on its back end (experiments.ar_slam3d): one flight of
``--frames`` frames estimated with the adaptive range, a fixed 25 m range and (``--full``) no range,
the paper's figures 7 (time per frame) and 8 (the track and its error), and the position NEES over
``--seeds`` shorter flights at checkpoints. Writes ``--out``/ar-slam3d-experiment.json and the two
figures (docs/ar-slam.md shows them).

    python tools/ar_slam3d.py [--frames 1600] [--seeds 30] [--full] [--out docs] [--jobs 2]
        [--baseline-frames 10] [--min-parallax 2] [--entry second] [--tag NAME]

``--tag``: write ar-slam3d-NAME.json and no figures (a variant beside the default run). ``--seeds 0``:
the long flights and their figures alone, the JSON's Monte Carlo kept. ``--jobs``: the Monte Carlo's
flights in that many processes.
``--rendered N``: instead, N flights of 300 rendered frames through the paper's front end
(experiments.ar_slam3d_rendered), rotation given and from VO, the corners matched by NCC and followed
(``tracked``): ar-slam3d-rendered.json; ``--rendered-cases``: only those, the file's others kept.
``--ground N``: instead, a flat-ground map (experiments.flat_ground) against the triangulated one on
N flights over flat ground and N over relief: ar-slam3d-flat-ground.json.
"""

from __future__ import annotations

import argparse
import functools
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from bus.statistics import chi2_band
from experiments.ar_slam3d import fly
from experiments.ar_slam3d_figures import figure_time, figure_track, summary
from experiments.ar_slam3d_rendered import fly as fly_rendered
from experiments.rendered_noise import tracked_pixel_sigma

CHECKPOINTS = (99, 199, 299)  # frames of the Monte Carlo flights (300 frames, 150 m)


def monte_carlo(seeds: int, two_frames: dict, jobs: int = 1) -> dict:
    """Position (3 dof) and vehicle (position and velocity, 6 dof) NEES at the checkpoints of ``seeds``
    300-frame flights, each range and association, the landmarks' mean NEES where they are identified,
    and the position RMSE over the flights (the root mean square of each flight's); full EKF-SLAM
    (no range) on the same flights, by id, is the accuracy reference."""
    low, high = chi2_band(3, runs=seeds)
    low6, high6 = chi2_band(6, runs=seeds)
    cases = {}
    runs = [(True, "adaptive"), (True, "fixed-25"), (True, "full"), (False, "adaptive"), (False, "fixed-25")]
    for identified, mode in runs:
        flight = functools.partial(fly, frames=300, mode=mode, identified=identified, **two_frames)
        with ProcessPoolExecutor(jobs) as pool:
            tracks = list(pool.map(flight, range(seeds)))
        position, errors = _position(tracks, (low, high))
        vehicle = _at_checkpoints(np.array([t.vehicle_nees() for t in tracks]))
        key = f"{mode}, {'identified' if identified else 'nn association'}"
        cases[key] = {
            **position,
            "checkpoint_vehicle_anees": vehicle,
            "vehicle_inside": [low6 <= m <= high6 for m in vehicle],
            "rmse_m": round(float(np.sqrt(np.mean(errors**2))), 4),
            "frame_ms_p99": round(float(np.percentile([t.frame_ms for t in tracks], 99)), 2),
        }
        if identified:  # the landmarks' NEES needs their true identities
            cases[key]["checkpoint_landmark_mean_nees"] = _at_checkpoints(np.array([t.landmark_nees for t in tracks]))
        print(key, cases[key], flush=True)
    full = cases["full, identified"]["rmse_m"]
    for case in cases.values():
        case["rmse_against_full"] = round(case["rmse_m"] / full, 3)
    return {
        "seeds": seeds,
        "checkpoints_frame": [c + 1 for c in CHECKPOINTS],
        "band_95": [round(low, 2), round(high, 2)],
        "band_95_vehicle_6dof": [round(low6, 2), round(high6, 2)],
        "cases": cases,
    }


GROUND_CASES = {  # the same flights over flat ground and over relief, each map triangulated and on a flat plane
    "flat ground, triangulated": {"relief": False, "flat_ground": False},
    "flat ground, flat-ground map": {"relief": False, "flat_ground": True},
    "relief, triangulated": {"relief": True, "flat_ground": False},
    "relief, flat-ground map": {"relief": True, "flat_ground": True},
}


def ground_monte_carlo(seeds: int, jobs: int = 1) -> dict:
    """A flat-ground map against the paper's triangulated one (experiments.flat_ground) on ``seeds``
    300-frame flights of each ground, the adaptive range, landmarks by id: the horizontal position's
    RMSE over the flights, each flight's final horizontal error, the position ANEES at the checkpoints."""
    band = chi2_band(3, runs=seeds)
    cases = {}
    for name, options in GROUND_CASES.items():
        with ProcessPoolExecutor(jobs) as pool:
            tracks = list(pool.map(functools.partial(fly, frames=300, mode="adaptive", **options), range(seeds)))
        position, _ = _position(tracks, band)
        horizontal = np.array([np.linalg.norm((t.estimate - t.truth)[:, :2], axis=1) for t in tracks])
        cases[name] = {
            **position,
            "horizontal_rmse_m": round(float(np.sqrt(np.mean(horizontal**2))), 3),
            "final_horizontal_error_m": [round(float(e), 2) for e in horizontal[:, -1]],
        }
        print(name, cases[name], flush=True)
    return {"seeds": seeds, "checkpoints_frame": [c + 1 for c in CHECKPOINTS],
            "band_95": [round(band[0], 2), round(band[1], 2)], "cases": cases}  # fmt: skip


RENDERED_CASES = {
    "given": {"rotation": "given"},
    "vo": {"rotation": "vo"},
    "given, tracked": {"rotation": "given", "tracked": True},
    "vo, tracked": {"rotation": "vo", "tracked": True},
    "given, tracked, R regrown": {"rotation": "given", "tracked": True, "regrow": True},
    "given, tracked, R regrown, 5-frame fallback": {
        "rotation": "given",
        "tracked": True,
        "regrow": True,
        "fallback_frames": 5,
    },
    "given, tracked, R regrown, 5-frame fallback, pixel noise measured": {
        "rotation": "given",
        "tracked": True,
        "regrow": True,
        "fallback_frames": 5,
        "sigma_px": "measured",
    },
}


def rendered_monte_carlo(seeds: int, jobs: int = 1, names: tuple[str, ...] = tuple(RENDERED_CASES)) -> dict:
    """The rendered flights (experiments.ar_slam3d_rendered), adaptive range: position NEES at the
    checkpoints, RMSE over the flights, the front end's failed frames and the last frame's rotation
    error, for the rotation given and from VO, each with the corners matched across the pair by NCC
    (the paper's) and followed from frame to frame (``tracked``), and with an emptied local map's range
    taken out to the frame's points at once (``regrow``): the cases ``names`` of RENDERED_CASES."""
    low, high = chi2_band(3, runs=seeds)
    cases = {}
    for key in names:
        told = {name: _measured(value) for name, value in RENDERED_CASES[key].items()}
        flight = functools.partial(fly_rendered, frames=300, mode="adaptive", **told)
        with ProcessPoolExecutor(jobs) as pool:
            flown = list(pool.map(flight, range(seeds)))
        position, errors = _position([track for track, _ in flown], (low, high))
        cases[key] = {
            **position,
            "position_nees_per_flight": _per_flight([track for track, _ in flown]),
            "rmse_m": round(float(np.sqrt(np.mean(errors**2))), 3),
            "final_error_m": [round(float(e), 2) for e in errors[:, -1]],
            "failed_frames": [c.failed for _, c in flown],
            "matches_per_frame": round(float(np.mean([c.matches / 300 for _, c in flown])), 1),
            "points_per_frame": round(float(np.mean([c.points / 300 for _, c in flown])), 1),
            "final_rotation_error_deg": [round(float(np.degrees(c.rotation_error_rad)), 2) for _, c in flown],
        }
        print(key, cases[key], flush=True)
    band = [round(low, 2), round(high, 2)]
    return {"seeds": seeds, "checkpoints_frame": [c + 1 for c in CHECKPOINTS], "band_95": band, "cases": cases}


def _position(tracks: list, band: tuple[float, float]) -> tuple[dict, np.ndarray]:
    """The flights' position ANEES at the checkpoints and whether each lies inside ``band``, and their
    position errors (flights, frames) m."""
    anees = _at_checkpoints(np.array([t.position_nees() for t in tracks]))
    inside = [band[0] <= m <= band[1] for m in anees]
    errors = np.array([np.linalg.norm(t.estimate - t.truth, axis=1) for t in tracks])
    return {"checkpoint_position_anees": anees, "inside": inside}, errors


def _measured(value):
    """A case's option as flown: ``"measured"`` (only ``sigma_px`` takes it) the followed corners' pixel
    noise measured on flights of their own (experiments.rendered_noise), anything else as it is."""
    return _pixel_sigma() if value == "measured" else value


@functools.cache
def _pixel_sigma() -> float:
    return tracked_pixel_sigma()


def _per_flight(tracks: list) -> list[list[float]]:
    """Each flight's position NEES at the checkpoints (flights, checkpoints)."""
    return [[round(float(t.position_nees()[c]), 2) for c in CHECKPOINTS] for t in tracks]


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
    parser.add_argument("--rendered", type=int, default=0, help="instead: this many rendered flights")
    parser.add_argument("--jobs", type=int, default=1, help="the Monte Carlo's flights in this many processes")
    parser.add_argument(
        "--rendered-cases", nargs="+", default=list(RENDERED_CASES), help="these rendered cases; the JSON's others kept"
    )
    parser.add_argument("--ground", type=int, default=0, help="instead: a flat-ground map against triangulation")
    args = parser.parse_args()
    if args.ground:
        path = args.out / "data" / "ar-slam3d-flat-ground.json"
        path.write_text(json.dumps(ground_monte_carlo(args.ground, args.jobs), indent=2) + "\n")
        return
    if args.rendered:
        names = tuple(args.rendered_cases)
        unknown = sorted(set(names) - set(RENDERED_CASES))
        if unknown:
            parser.error(f"--rendered-cases: unknown {unknown}; the cases are {sorted(RENDERED_CASES)}")
        path = args.out / "data" / "ar-slam3d-rendered.json"
        result = rendered_monte_carlo(args.rendered, args.jobs, names)
        kept = json.loads(path.read_text()) if path.exists() else {}
        if kept.get("seeds") == args.rendered:
            result["cases"] = {**kept["cases"], **result["cases"]}
        path.write_text(json.dumps(result, indent=2) + "\n")
        return
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
    (args.out / "data").mkdir(parents=True, exist_ok=True)
    name = f"ar-slam3d-{args.tag}.json" if args.tag else "ar-slam3d-experiment.json"
    if args.seeds:
        result["monte_carlo"] = monte_carlo(args.seeds, two_frames, args.jobs)
    elif (args.out / "data" / name).exists():  # the flights and figures again, the Monte Carlo kept
        result["monte_carlo"] = json.loads((args.out / "data" / name).read_text()).get("monte_carlo")
    (args.out / "data" / name).write_text(json.dumps(result, indent=2) + "\n")
    if not args.tag:
        figure_time(tracks, args.out / "img" / "ar-slam3d-frame-time.png")
        figure_track(tracks, args.out / "img" / "ar-slam3d-track.png")


if __name__ == "__main__":
    main()
