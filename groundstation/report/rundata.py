"""Reads a run directory for the report, tolerating a broken or partial one (killed run).

Nothing here raises for a missing or damaged file: every problem is recorded in ``RunData.problems``
as one sentence a user can act on, and the report shows what is there.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bus.errors import SwarmlocError

FAULT_MARKER_EVENTS = frozenset(
    {"vehicle_lost", "vehicle_restarted", "estimator_reset", "gnss_unhealthy", "gnss_healthy"}
)


class ReportError(SwarmlocError):
    """The folder given is not a run directory at all."""


@dataclass
class RunData:
    path: Path
    config: dict[str, Any] | None = None
    summary: dict[str, Any] | None = None
    timing: dict[str, Any] | None = None
    metrics: dict[str, np.ndarray] = field(default_factory=dict)  # column name -> (N,) values
    events: list[dict[str, Any]] = field(default_factory=list)
    est: dict[int, np.ndarray] = field(default_factory=dict)  # vehicle -> (N, 8) TUM rows
    truth: dict[int, np.ndarray] = field(default_factory=dict)  # vehicle -> (N, 8) TUM rows
    maps: dict[int, tuple[np.ndarray, np.ndarray]] = field(
        default_factory=dict
    )  # SLAM vehicle -> xy (m, 2), cov (m, 2, 2)
    problems: list[str] = field(default_factory=list)

    @property
    def vehicles(self) -> list[int]:
        ids = set(self.est) | set(self.truth)
        if "vehicle" in self.metrics:
            ids |= set(np.unique(self.metrics["vehicle"]).astype(int).tolist())
        if self.summary:
            ids |= {int(v) for v in self.summary.get("vehicles", {})}
        return sorted(ids)

    def rows_of(self, vehicle_id: int) -> dict[str, np.ndarray]:
        """The metrics columns restricted to one vehicle, in time order."""
        if not self.metrics:
            return {}
        mask = self.metrics["vehicle"] == vehicle_id
        order = np.argsort(self.metrics["t_s"][mask], kind="stable")
        return {name: column[mask][order] for name, column in self.metrics.items()}

    def marker_events(self) -> list[dict[str, Any]]:
        """Events worth a marker on time plots: faults and what they cause."""
        return [
            e
            for e in self.events
            if str(e.get("event", "")).startswith("fault_") or e.get("event") in FAULT_MARKER_EVENTS
        ]

    def zones(self) -> list[dict[str, Any]]:
        """Jamming or spoofing zones announced in the events: ``{"center_m": [x, y], "radius_m": r, ...}``."""
        seen: dict[str, dict[str, Any]] = {}
        for e in self.events:
            zone = e.get("zone") if e.get("event") == "fault_added" else None
            if isinstance(zone, dict) and "center_m" in zone and "radius_m" in zone:
                seen[str(e.get("name", len(seen)))] = {
                    **zone,
                    "fault": e.get("fault", "zone"),
                    "name": e.get("name", ""),
                    "t_s": e.get("t_s"),
                }
        return list(seen.values())


def load_run(path: Path) -> RunData:
    """Everything the report needs from ``path``; raises ReportError only if it is no run directory."""
    path = Path(path)
    if not path.is_dir():
        raise ReportError(f"run directory {path} does not exist")
    known = ("config.json", "summary.json", "metrics.csv", "events.jsonl", "tum")
    if not any((path / name).exists() for name in known):
        raise ReportError(f"{path} is not a run directory: it has none of {', '.join(known)}")
    data = RunData(path=path)
    data.config = _read_json(path / "config.json", data.problems)
    data.summary = _read_json(
        path / "summary.json",
        data.problems,
        missing="summary.json is missing: the run did not finish (killed or still running); "
        "counters and the final table are unavailable, RMSE is computed from metrics.csv",
    )
    data.timing = _read_json(path / "timing.json", data.problems)
    data.metrics = _read_metrics(path / "metrics.csv", data.problems)
    data.events = _read_events(path / "events.jsonl", data.problems)
    for kind, target in (("est", data.est), ("truth", data.truth)):
        for file in sorted((path / "tum").glob(f"{kind}_v*.tum")):
            rows = _read_rows(file, 8, data.problems)
            if len(rows):
                target[int(file.stem.split("_v")[1])] = rows
    if not data.est:
        data.problems.append("tum/ has no estimated trajectories: the map shows no tracks")
    for file in sorted(path.glob("map_v*.json")):
        landmarks = _read_landmarks(file, data.problems)
        if landmarks is not None:
            data.maps[int(file.stem.split("_v")[1])] = landmarks
    return data


def _read_landmarks(file: Path, problems: list[str]) -> tuple[np.ndarray, np.ndarray] | None:
    """A SLAM vehicle's map_v<id>.json as positions (m, 2) and covariances (m, 2, 2); None if damaged."""
    record = _read_json(file, problems)
    try:
        xy = np.array(record["xy_m"], dtype=float).reshape(-1, 2)
        packed = np.array(record["cov_m2"], dtype=float).reshape(-1, 3)
        if len(xy) != len(packed) or not (np.isfinite(xy).all() and np.isfinite(packed).all()):
            raise ValueError("sizes or values")
    except (TypeError, KeyError, ValueError) as exc:
        problems.append(f"{file.name} is damaged and was ignored ({exc})")
        return None
    cov = np.stack(
        [np.stack([packed[:, 0], packed[:, 1]], axis=1), np.stack([packed[:, 1], packed[:, 2]], axis=1)], axis=1
    )
    return xy, cov


def _read_json(file: Path, problems: list[str], missing: str | None = None) -> dict[str, Any] | None:
    if not file.exists():
        problems.append(missing or f"{file.name} is missing")
        return None
    try:
        return json.loads(file.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        problems.append(f"{file.name} is damaged and was ignored ({exc})")
        return None


def _read_rows(
    file: Path, width: int, problems: list[str], skip_header: bool = False, sep: str | None = None
) -> np.ndarray:
    """(N, width) floats from a text table, an empty field NaN (metrics.csv's height columns of a level
    vehicle); lines of another width or not numeric are skipped and counted (the last line of a killed
    run is often cut short)."""
    lines = file.read_text(errors="replace").splitlines()[1 if skip_header else 0 :]
    rows, bad = [], 0
    for line in lines:
        fields = line.split(sep)
        try:
            values = [float(f) if f else math.nan for f in fields]
        except ValueError:
            values = []
        if len(values) == width:
            rows.append(values)
        elif line.strip():
            bad += 1
    if bad:
        problems.append(
            f"{file.relative_to(file.parents[1]) if file.parent.name == 'tum' else file.name}: "
            f"{bad} malformed line(s) skipped"
        )
    return np.array(rows, dtype=float).reshape(-1, width)


def _read_metrics(file: Path, problems: list[str]) -> dict[str, np.ndarray]:
    if not file.exists():
        problems.append("metrics.csv is missing: no error, RMSE or NEES plots")
        return {}
    header = file.read_text(errors="replace").split("\n", 1)[0].strip().split(",")
    if "t_s" not in header or "vehicle" not in header:
        problems.append("metrics.csv has no valid header: no error, RMSE or NEES plots")
        return {}
    rows = _read_rows(file, len(header), problems, skip_header=True, sep=",")
    if "cov_xy_m2" not in header:
        problems.append("metrics.csv has no cov_xy_m2 column (older run): ellipses ignore x-y correlation")
    return {name: rows[:, i] for i, name in enumerate(header)}


def _read_events(file: Path, problems: list[str]) -> list[dict[str, Any]]:
    if not file.exists():
        problems.append("events.jsonl is missing: no fault markers")
        return []
    events, bad = [], 0
    for line in file.read_text(errors="replace").splitlines():
        try:
            record = json.loads(line)
        except json.JSONDecodeError:
            bad += bool(line.strip())
            continue
        if isinstance(record, dict):
            events.append(record)
        else:
            bad += 1
    if bad:
        problems.append(f"events.jsonl: {bad} malformed line(s) skipped")
    return events
