"""The 3-D AR-EKF-SLAM back end's cost per frame (experiments.ar_slam3d), the issue's adaptive-range
targets: over a long flight of uniform landmarks the adaptive range's p99 per frame stays flat as the
map grows (its p99 near 2000 mapped landmarks at most 1.5x its p99 near 200), and over the flight with
a dense town it stays below the fixed 25 m range's (the paper's figure 7). A frame's cost is the back
end's prediction and frame (association by id, updates, entry, retirement, and the covariances it
asks the triangulation for at its landmarks' predictions), the frame's own triangulation not
included. Mapped: landmarks entered so far (in the state or retired)."""

from __future__ import annotations

import numpy as np

from bench.common import Row
from experiments.ar_slam3d import fly

FLAT, BINS = 1.5, (200, 2000)
FULL = 500  # mapped landmarks by which the local map has filled (its first frames hold few)


def p99_near(track, landmarks: int) -> tuple[float, int]:
    """p99 (ms) of the frames with 0.9 * landmarks < mapped <= landmarks, and how many there were."""
    near = (track.mapped > 0.9 * landmarks) & (track.mapped <= landmarks)
    return (float(np.percentile(track.frame_ms[near], 99)) if near.any() else float("nan")), int(near.sum())


def run(quick: bool = False) -> list[Row]:
    rows = []
    long = fly(0, 2500 if quick else 5000, "adaptive", town=False)
    (low, n_low), (high, n_high) = (p99_near(long, b) for b in BINS)
    for bin_, value, n in ((BINS[0], low, n_low), (BINS[1], high, n_high)):
        case = f"adaptive, uniform landmarks, {bin_} mapped ({n} frames)"
        rows.append(Row("ar-slam 3-D", case, "p99 per frame", round(value, 3), "ms", "-", None))
    ratio = high / low if low > 0 else float("nan")
    flat = bool(np.isfinite(ratio) and ratio <= FLAT)
    rows.append(
        Row(
            "ar-slam 3-D",
            f"adaptive, {BINS[1]} against {BINS[0]} mapped",
            "p99 ratio",
            round(ratio, 2),
            "x",
            f"<= {FLAT}x",
            flat if np.isfinite(ratio) else None,
        )
    )
    rows += _full_map_rows(long, high, n_high)
    town = {mode: fly(0, 1600, mode) for mode in ("adaptive", "fixed-25")}
    p99 = {mode: float(np.percentile(track.frame_ms, 99)) for mode, track in town.items()}
    for mode, value in p99.items():
        target = "< fixed 25 m" if mode == "adaptive" else "-"
        met = (value < p99["fixed-25"]) if mode == "adaptive" else None
        rows.append(
            Row(
                "ar-slam 3-D",
                f"{mode}, 1600 frames with a dense town",
                "p99 per frame",
                round(value, 3),
                "ms",
                target,
                met,
            )
        )
    return rows


def _full_map_rows(track, high: float, n_high: int) -> list[Row]:
    """The same flight's p99 near FULL mapped landmarks, where the local map is as full as near 2000,
    and the ratio of the two: whether the cost grows with the map once the range holds it. Each row
    says how many landmarks the state held (mean) in the frames it takes."""
    full, n_full = p99_near(track, FULL)
    held = {b: float(track.landmarks[(track.mapped > 0.9 * b) & (track.mapped <= b)].mean()) for b in (*BINS, FULL)}
    ratio = high / full if full > 0 else float("nan")
    details = {f"state landmarks near {b} mapped (mean)": round(v, 1) for b, v in held.items()}
    return [
        Row(
            "ar-slam 3-D",
            f"adaptive, uniform landmarks, {FULL} mapped ({n_full} frames)",
            "p99 per frame",
            round(full, 3),
            "ms",
            "-",
            None,
        ),
        Row(
            "ar-slam 3-D",
            f"adaptive, {BINS[1]} against {FULL} mapped (the local map full at both)",
            "p99 ratio",
            round(ratio, 2),
            "x",
            f"<= {FLAT}x",
            bool(np.isfinite(ratio) and ratio <= FLAT),
            details,
        ),
    ]
