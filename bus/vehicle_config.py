"""A vehicle's estimator settings (:class:`VehicleConfig`, with ``ar-ekf-slam``'s adaptive range
:class:`ArSlamConfig`). Part of the swarm configuration (bus.config) and of the much smaller one a
vehicle process is given (``VehicleProcessConfig``)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field, model_validator

from bus.estimators import ESTIMATORS, EstimatorName
from bus.strict_model import Strict as _Strict


class ArSlamConfig(_Strict):
    """``ar-ekf-slam``'s adaptive observation range (the AR-EKF-SLAM paper's values as defaults)."""

    r0_m: float = Field(25.0, gt=0, le=10_000, description="the range R a flight starts with (m)")
    r_max_m: float = Field(35.0, gt=0, le=10_000, description="R grows no further than this (m)")
    n_min: int = Field(8, ge=1, le=100_000, description="fewer landmarks in the local map: R grows")
    n_max: int = Field(50, ge=2, le=100_000, description="more landmarks in the local map: R shrinks")
    dr_m: float = Field(0.1, gt=0, le=1_000, description="how much R changes per camera frame (m)")
    reentry: Literal["reinit", "ci", "naive"] = Field(
        "reinit",
        description="a retired landmark seen again: reinit (initialised as new), ci (and its old marginal "
        "fused by Covariance Intersection) or naive (its old marginal put back uncorrelated: over-confident)",
    )

    @model_validator(mode="after")
    def _a_range_that_can_settle(self) -> ArSlamConfig:
        if self.r0_m > self.r_max_m:
            raise ValueError(f"r0_m {self.r0_m:g} is above r_max_m {self.r_max_m:g}")
        if self.n_min >= self.n_max:
            raise ValueError(f"n_min {self.n_min} must be below n_max {self.n_max}")
        if self.dr_m >= self.r_max_m:
            raise ValueError(f"dr_m {self.dr_m:g} must be below r_max_m {self.r_max_m:g}")
        return self


class Cooperation(_Strict):
    """How a vehicle fuses its neighbours' fixes (vehicle.models.cooperative)."""

    enabled: bool = Field(True, description="fuse ranging to neighbours with their broadcast estimates (CI)")
    fusion: Literal["split-ci", "ci", "paper", "naive"] = Field(
        "split-ci",
        description="split-ci: Covariance Intersection scaling only the neighbour's share, the radio's "
        "own noise kept whole (consistent whatever the correlation); ci: plain CI; paper: CI of the position "
        "the fix implies (paper eq. 4.10); naive: a plain Kalman update that treats the neighbour's estimate as "
        "independent (double counts)",
    )
    weight: Literal["optimal", "closed-form"] = Field(
        "optimal",
        description="CI weight: optimal (maximum "
        "pose information, w = 1 skips the fix) or closed-form "
        "(plain CI's best weight in closed form)",
    )
    latency_s: float = Field(0.1, ge=0, le=5, description="ranging waits this long for the neighbour's estimate")


class AdaptiveNoise(_Strict):
    """IAE: the GNSS and ranging noise learnt from the innovations (vehicle.estimators.adaptive)."""

    enabled: bool = Field(
        False,
        description="estimate the GNSS and ranging noise covariances from the innovations of the last "
        "window fixes instead of trusting the datasheet (never below it: a CI-fused covariance is a bound, "
        "so a quieter-looking sensor is its slack)",
    )
    window: int = Field(40, ge=5, le=10_000, description="fixes per sensor")


class NeighbourMonitor(_Strict):
    """Judging the neighbours (vehicle.trust; docs: liars, security)."""

    enabled: bool = Field(
        True,
        description="judge each neighbour's fixes for consistency and stop fusing a neighbour that lies",
    )
    max_compromised: int = Field(
        1,
        ge=0,
        le=250,
        description="f: how many vehicles may be compromised (their own keys, any lie or accusation); a "
        "neighbour a vehicle cannot judge itself is distrusted on the word of more than f (docs: security)",
    )
    rule: Literal["evidence", "quorum-only"] = Field(
        "evidence",
        description="evidence: the others' word never outweighs a vehicle's own evidence and accusers are "
        "judged; quorum-only: the rule before, a quorum's word decides (a control; docs: security)",
    )


class RealtimeLoop(_Strict):
    """The estimator loop in realtime (vehicle.process.loops)."""

    feed_lead_s: float = Field(
        0.01,
        ge=0,
        le=1,
        description="a vehicle's cycle at sim time t is due this long (wall time) after the world's "
        "tick at t, plus its own phase of the period: the time the world's sensor batch is given to reach it",
    )
    allowance_s: float = Field(
        0.005, ge=0, le=1, description="a cycle waits this long past its deadline for the tick's sensor batch"
    )
    priority: int = Field(
        10,
        ge=0,
        le=99,
        description="the estimator loop runs under SCHED_FIFO at this priority when the kernel allows "
        "it (root, CAP_SYS_NICE or `ulimit -r`), else under the fair scheduler; 0: always the fair scheduler "
        "(vehicle.process.scheduling)",
    )


# keys of the flat configuration before the parts, and where each is now
MOVED = {
    "cooperative": "cooperation.enabled",
    "cooperative_fusion": "cooperation.fusion",
    "ci_weight": "cooperation.weight",
    "v2v_latency_s": "cooperation.latency_s",
    "adaptive_noise": "adaptive.enabled",
    "adaptive_window": "adaptive.window",
    "neighbour_monitor": "monitor.enabled",
    "max_compromised": "monitor.max_compromised",
    "trust_rule": "monitor.rule",
    "realtime_feed_lead_s": "realtime.feed_lead_s",
    "realtime_allowance_s": "realtime.allowance_s",
    "realtime_priority": "realtime.priority",
}


class VehicleConfig(_Strict):
    estimator: EstimatorName = Field(
        "ekf",
        description="the estimator every vehicle runs: "
        + "; ".join(f"{name}: {entry.summary}" for name, entry in ESTIMATORS.items()),
    )
    landmarks: tuple[tuple[int, float, float], ...] = Field(
        (), max_length=10_000, description="known-map: the surveyed landmarks, (id, x m, y m)"
    )
    features: Literal["sift", "orb"] = Field("sift", description="ekf-slam, ar-ekf-slam: keypoint detector")
    ar: ArSlamConfig = Field(default_factory=ArSlamConfig, description="ar-ekf-slam: the adaptive range")
    association: Literal["descriptor", "nn", "jcbb", "aco"] = Field(
        "descriptor",
        description="ekf-slam, ar-ekf-slam: which keypoint is which landmark: descriptor match with a rigid "
        "consensus, or among each landmark's descriptor shortlist Mahalanobis nearest neighbour (nn), joint "
        "compatibility branch and bound (jcbb) or the ant colony (aco)",
    )
    odometry: Literal["wheel", "visual"] = Field(
        "wheel",
        description="where every vehicle's speed comes from: its wheels, or visual odometry from consecutive "
        "camera frames (a vehicle without wheels; needs sensors.camera_rate_hz)",
    )
    visual_odometry_vehicles: tuple[int, ...] = Field(
        (), max_length=1000, description="these vehicles use visual odometry whatever `odometry` says"
    )
    loop_rate_hz: float = Field(50.0, gt=0, le=1000)
    gate_probability: float = Field(0.9995, gt=0.5, lt=1.0, description="chi-square gate for GNSS")
    heartbeat_period_s: float = Field(1.0, gt=0)
    status_period_s: float = Field(1.0, gt=0)
    fusion_horizon_s: float = Field(
        0.5, ge=0, le=10, description="late measurements up to this old are still fused in order"
    )
    cooperation: Cooperation = Field(default_factory=Cooperation, description="fusing the neighbours' fixes")
    adaptive: AdaptiveNoise = Field(default_factory=AdaptiveNoise, description="IAE")
    monitor: NeighbourMonitor = Field(default_factory=NeighbourMonitor, description="judging the neighbours")
    realtime: RealtimeLoop = Field(default_factory=RealtimeLoop, description="the realtime loop")

    @model_validator(mode="before")
    @classmethod
    def _keys_of_a_part(cls, data: Any) -> Any:
        """A key that now belongs to a part (``cooperative_fusion``) is refused naming its place."""
        moved = sorted(MOVED.keys() & data.keys()) if isinstance(data, dict) else []
        if moved:
            key = moved[0]
            raise ValueError(f"vehicle.{key} is now vehicle.{MOVED[key]}")
        return data

    def visual_odometry(self, vehicle_id: int) -> bool:
        """Does this vehicle take its speed from visual odometry?"""
        return self.odometry == "visual" or vehicle_id in self.visual_odometry_vehicles

    mavlink_rate_hz: float = Field(
        10.0,
        gt=0,
        le=1000,
        description="ODOMETRY to the ground station (<= loop rate; "
        "a telemetry rate: the ground station scores every estimate it receives)",
    )
    world_timeout_s: float = Field(60.0, gt=0, description="a vehicle whose world is gone this long gives up")
