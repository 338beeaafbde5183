"""The run directory: config.json, metrics.csv, events.jsonl, summary.json, timing.json, tum/.

Files are appended and flushed at least every ``flush_period_s`` of wall time and of sim time
(lockstep runs many times faster than real time), so killing the ground station loses at most about
the last second of metrics. A restarted ground station appends.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from groundstation.scoring import Score

METRICS_HEADER = (
    "t_s,vehicle,err_x_m,err_y_m,err_pos_m,err_yaw_rad,sigma_x_m,sigma_y_m,sigma_yaw_rad,nees,reset_counter,cov_xy_m2,"
    "err_alt_m,sigma_alt_m,nees_alt\n"
)  # the last three: the height's score where the vehicle estimates its height (groundstation.scoring), else empty


def drop_partial_line(path: Path) -> None:
    """Cut a half-written last line (a killed writer) so that appended lines stay well formed."""
    if not path.exists() or path.stat().st_size == 0:
        return
    with path.open("rb+") as handle:
        data = handle.read()
        if not data.endswith(b"\n"):
            handle.truncate(data.rfind(b"\n") + 1)


def _height_columns(s: Score) -> str:
    """metrics.csv's err_alt_m, sigma_alt_m and nees_alt of a score: empty where no height is estimated."""
    if math.isnan(s.altitude_nees):
        return ",,"
    return f"{s.altitude_error_m:.6f},{s.altitude_sigma_m:.6f},{s.altitude_nees:.6f}"


class RunDirectory:
    def __init__(self, path: Path, *, flush_period_s: float = 0.5, recording: Any = None) -> None:
        self.path = Path(path)
        self.recording = recording  # groundstation.recording.Recording: the same scores and events for Foxglove
        (self.path / "tum").mkdir(parents=True, exist_ok=True)
        self._flush_period_s = flush_period_s
        self._last_flush = time.monotonic()
        self._flushed_sim_us = 0
        self._metrics = self._open("metrics.csv", METRICS_HEADER)
        self._events = self._open("events.jsonl")
        self._tum: dict[str, TextIO] = {}

    def _open(self, name: str, header: str = "") -> TextIO:
        path = self.path / name
        drop_partial_line(path)
        fresh = not path.exists() or path.stat().st_size == 0
        handle = path.open("a", encoding="utf-8")
        if fresh and header:
            handle.write(header)
        return handle

    def _tum_file(self, kind: str, vehicle_id: int) -> TextIO:
        name = f"tum/{kind}_v{vehicle_id}.tum"
        if name not in self._tum:
            self._tum[name] = self._open(name)
        return self._tum[name]

    def write_scores(self, scores: list[Score]) -> None:
        """A metrics row and an estimate and a truth TUM line per score (the truth's z the estimate's
        where the vehicle flies level, the true height's where it estimates its own). The numbers are read out of
        numpy once per score (``tolist``) and the half-yaw sines and cosines worked out for the whole
        list at once: the same text as formatting each numpy scalar, at a third of the cost."""
        half_yaws = np.array([(s.estimate.yaw_rad, s.truth_pose[2]) for s in scores], dtype=float).reshape(-1, 2) / 2
        for s, (sin_est, sin_truth), (cos_est, cos_truth) in zip(
            scores, np.sin(half_yaws).tolist(), np.cos(half_yaws).tolist()
        ):
            ex, ey, eyaw = s.error_m.tolist()
            sx, sy, syaw = s.sigma.tolist()
            x, y, z = s.estimate.position_m.tolist()
            tx, ty = s.truth_pose[:2].tolist()
            tz = z if math.isnan(s.altitude_error_m) else z + s.altitude_error_m  # NED: the true height's
            t_s = s.stamp_us * 1e-6
            self._metrics.write(
                f"{t_s:.6f},{s.vehicle_id},{ex:.6f},{ey:.6f},{s.position_error_m:.6f},{eyaw:.6f},{sx:.6f},"
                f"{sy:.6f},{syaw:.6f},{s.nees:.6f},{s.reset_counter},{s.pose_covariance[0, 1].item():.9f},"
                f"{_height_columns(s)}\n"
            )
            # TUM: timestamp tx ty tz qx qy qz qw (a yaw-only attitude)
            self._tum_file("est", s.vehicle_id).write(
                f"{t_s:.6f} {x:.6f} {y:.6f} {z:.6f} 0 0 {sin_est:.9f} {cos_est:.9f}\n"
            )
            self._tum_file("truth", s.vehicle_id).write(
                f"{t_s:.6f} {tx:.6f} {ty:.6f} {tz:.6f} 0 0 {sin_truth:.9f} {cos_truth:.9f}\n"
            )
        if self.recording is not None and scores:
            self.recording.scores(scores)
        self.maybe_flush(scores[-1].stamp_us if scores else None)

    def event(self, kind: str, stamp_us: int, /, **fields: Any) -> None:
        record = {"t_s": round(stamp_us * 1e-6, 6), "event": kind, **fields}
        self._events.write(json.dumps(record, sort_keys=True) + "\n")
        if self.recording is not None:
            self.recording.event(record, stamp_us)
        self.maybe_flush()

    def write_json(self, name: str, data: dict[str, Any]) -> None:
        tmp = self.path / f".{name}.tmp"
        tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
        tmp.replace(self.path / name)

    def write_maps(self, maps: dict[int, dict[str, Any]]) -> None:
        """Each SLAM vehicle's last reported landmark map as ``map_v<id>.json``, in vehicle order."""
        for vid, record in sorted(maps.items()):
            self.write_json(f"map_v{vid}.json", record)

    def write_layouts(self, layouts: dict[str, str]) -> None:
        """The viewers' layouts for this run (groundstation.layout), by file name."""
        for name, text in layouts.items():
            tmp = self.path / f".{name}.tmp"
            tmp.write_text(text)
            tmp.replace(self.path / name)

    def maybe_flush(self, sim_us: int | None = None) -> None:
        """Flush when ``flush_period_s`` of wall time, or of sim time (``sim_us``: newest row), passed."""
        sim_due = sim_us is not None and sim_us - self._flushed_sim_us >= self._flush_period_s * 1e6
        if sim_due or time.monotonic() - self._last_flush >= self._flush_period_s:
            self.flush()
            if sim_us is not None:
                self._flushed_sim_us = sim_us

    def flush(self) -> None:
        for handle in (self._metrics, self._events, *self._tum.values()):
            handle.flush()
        self._last_flush = time.monotonic()

    def close(self) -> None:
        self.flush()
        if self.recording is not None:
            self.recording.close()
        for handle in (self._metrics, self._events, *self._tum.values()):
            handle.close()
