"""The interface every estimator implements, and what the node reads from it (kiss-icp style: one
small protocol, one module per variant, ``vehicle.estimators.get_estimator(config)`` picks one).

The node knows only this interface: it hands over measurements in stamp order (``handle``), runs one
``cycle`` per loop period (propagation, health checks and divergence recovery live inside the
estimator), asks for the ``estimate`` it publishes as ODOMETRY and the ``status`` behind
ESTIMATOR_STATUS, takes ``notices`` (STATUSTEXT lines) and, from a SLAM estimator, its
``landmark_map`` (positions (m, 2), covariances (m, 2, 2); None without a map). The fusion horizon uses ``snapshot`` /
``restore`` to go back in time for late measurements.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from bus.mavlink_codec import EstimatorStatus, StateEstimate

SEVERITY_WARNING, SEVERITY_INFO = 4, 6  # MAV_SEVERITY


@dataclass
class EstimatorCounters:
    """Cumulative counts an estimator reports (VehicleStatus)."""

    gnss_accepted: int = 0
    gnss_rejected: int = 0
    stale: int = 0
    resets: int = 0
    v2v_fused: int = 0
    v2v_rejected: int = 0
    landmarks: int = 0            # SLAM: landmarks in the map
    landmarks_updated: int = 0    # SLAM: landmarks the last usable camera frame updated
    frames_used: int = 0          # SLAM: camera frames through the front end


@dataclass(frozen=True)
class Notice:
    """Something the vehicle should say (STATUSTEXT), stamped in sim time; ``status_changed`` asks
    for an ESTIMATOR_STATUS at once (GNSS health)."""

    stamp_us: int
    severity: int
    text: str
    status_changed: bool = False


class Estimator(Protocol):
    name: str
    counters: EstimatorCounters

    @property
    def initialized(self) -> bool: ...
    def handle(self, topic: str, msg: Any) -> None: ...
    def cycle(self, t_us: int) -> None: ...
    def estimate(self, t_us: int, reset_counter: int) -> StateEstimate: ...
    def status(self, t_us: int) -> EstimatorStatus: ...
    def snapshot(self) -> Any: ...
    def restore(self, snapshot: Any) -> None: ...
    def take_notices(self) -> list[Notice]: ...
    def landmark_map(self) -> tuple[np.ndarray, np.ndarray] | None: ...
