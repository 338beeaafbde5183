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
    """Per-vehicle tallies (the planar pose's, its consistency, and the height's where it was scored) and
    the last scored stamp (us) from the complete lines of metrics.csv."""
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
            tally.add_sample(t_us * 1e-6, err, nees, bounds)
            height = _height_score(row)
            if height is not None:
                tally.add_altitude(t_us * 1e-6, *height)
            last_us[vid] = max(last_us.get(vid, t_us), t_us)
    return tallies, last_us


def _height_score(row: dict) -> tuple[float, float] | None:
    """A metrics row's height error (m) and NEES, None where it has none (a level vehicle, or a file
    written before the height was scored)."""
    try:
        return float(row["err_alt_m"]), float(row["nees_alt"])
    except (KeyError, TypeError, ValueError):
        return None


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
