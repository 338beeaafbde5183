"""What one estimator did over the ar-slam experiment's flight (experiments.ar_slam), as its figures
(experiments.ar_slam_figures) and its table read it."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Track:
    """What one estimator did over the flight: per second (t_s, squared x error, position error,
    pose NEES, state size) and per camera frame (time [ms], association counts)."""

    t_s: list[float] = field(default_factory=list)
    x_error_m2: list[float] = field(default_factory=list)
    error_m: list[float] = field(default_factory=list)
    nees: list[float] = field(default_factory=list)
    state_dim: list[int] = field(default_factory=list)
    frame_ms: list[float] = field(default_factory=list)
    pairs: int = 0
    correct: int = 0
    opportunities: int = 0
    gap: list[float] = field(default_factory=list)
    vo_failures: int = 0
