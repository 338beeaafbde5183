"""What the 3-D experiment (experiments.ar_slam3d) shows of a flight: its summary, the paper's figure 7
(time per frame, landmarks in the state, the range) and figure 8 (true against estimated track, the
position error and the 1-sigma claimed). Shared by `swarm experiment ar-slam`'s 3-D cases and
tools/ar_slam3d.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from experiments.ar_slam3d import Track

UNBOUNDED_M = 1_000.0  # a range this long is none (full EKF-SLAM's is 10 km)


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
    for i, (name, track) in enumerate(tracks.items()):
        frames, colour = np.arange(1, len(track.frame_ms) + 1), f"C{i}"  # a case's colour in every panel
        top.plot(frames, track.frame_ms, lw=0.6, label=name, color=colour)
        middle.plot(frames, track.landmarks, lw=0.8, label=name, color=colour)
        bounded = track.radius_m < UNBOUNDED_M  # full EKF-SLAM's range keeps every landmark: not drawn
        bottom.plot(frames[bounded], track.radius_m[bounded], lw=0.8, color=colour)
    top.set_ylabel("time per frame [ms]")
    top.set_yscale("log")
    top.legend()
    middle.set_ylabel("landmarks in the state")
    bottom.set_ylabel("range R [m]")
    unbounded = [name for name, track in tracks.items() if (track.radius_m >= UNBOUNDED_M).all()]
    if unbounded:
        bottom.set_title(f"no range (every landmark kept): {', '.join(unbounded)}", fontsize="small")
    bottom.set_ylim(0, 40)
    bottom.set_xlabel("frame")
    fig.suptitle("3-D AR-EKF-SLAM: per-frame cost of each case (paper's fig. 7)")
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
