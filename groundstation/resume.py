"""A restarted ground station picks up its run directory: the tallies of what was already scored
(from metrics.csv) and the event counts (from events.jsonl), so summary.json covers the whole run."""

from __future__ import annotations

import csv
import json
from collections import Counter
from pathlib import Path

from groundstation.scoring import Tally

UNCOUNTED_EVENTS = ("vehicle_left", "vehicle_lost", "vehicle_message", "run_ended")


def resume_run(run_dir: Path, bounds: tuple[float, float]) -> tuple[dict[int, Tally], dict[int, int]] | None:
    """The tallies and last scored stamps of a run directory a previous ground station of this run
    was writing (``resume_tallies`` of its metrics.csv), None when it scored nothing yet."""
    tallies, last_us = resume_tallies(run_dir / "metrics.csv", bounds)
    return (tallies, last_us) if tallies else None


def resume_tallies(path: Path, bounds: tuple[float, float]) -> tuple[dict[int, Tally], dict[int, int]]:
    """Per-vehicle tallies and the last scored stamp (us) from the complete lines of metrics.csv."""
    tallies: dict[int, Tally] = {}
    last_us: dict[int, int] = {}
    if not path.exists():
        return tallies, last_us
    with path.open(newline="") as handle:
        for row in csv.DictReader(line for line in handle if line.endswith("\n")):
            try:
                vid, err, nees, t_us = (
                    int(row["vehicle"]),
                    float(row["err_pos_m"]),
                    float(row["nees"]),
                    round(float(row["t_s"]) * 1e6),
                )
            except (KeyError, TypeError, ValueError):
                continue
            tally = tallies.setdefault(vid, Tally())
            tally.samples += 1
            tally.sum_sq_position_m2 += err * err
            tally.max_position_error_m = max(tally.max_position_error_m, err)
            tally.sum_nees += nees
            tally.nees_inside += int(bounds[0] <= nees <= bounds[1])
            last_us[vid] = max(last_us.get(vid, t_us), t_us)
    return tallies, last_us


def resume_events(path: Path) -> Counter[str]:
    """Counts of the events already logged (those the summary counts)."""
    counts: Counter[str] = Counter()
    if not path.exists():
        return counts
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            kind = json.loads(line).get("event")
        except (json.JSONDecodeError, AttributeError):
            continue
        if isinstance(kind, str) and kind not in UNCOUNTED_EVENTS:
            counts[kind] += 1
    return counts
