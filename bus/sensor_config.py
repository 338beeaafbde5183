"""The sensors' configuration: the datasheet every vehicle is told (:class:`SensorSpec`, also the
simulated sensors' rates and noise) and what the simulated world adds to it that no filter models
(:class:`SensorTruth`; ``HONEST_WORLD`` and the ``HONEST_DATASHEET`` its filters are given). Part of
the swarm configuration (bus.config)."""

from __future__ import annotations

from pydantic import Field, create_model, model_validator

from bus.sensors import SENSORS
from bus.strict_model import Strict as _Strict


class _BuiltInSensors(_Strict):
    """Rates and noise of the simulated sensors (also the vehicles' datasheet noise model)."""

    imu_rate_hz: float = Field(100.0, gt=0, le=1000)
    gyro_sigma_radps: float = Field(0.01, ge=0)
    gyro_bias_sigma_radps: float = Field(0.005, ge=0, description="initial gyro bias spread")
    gyro_bias_walk_radps_rtsec: float = Field(0.0005, ge=0)
    accel_sigma_mps2: float = Field(0.05, ge=0)
    odom_rate_hz: float = Field(50.0, gt=0, le=1000)
    odom_speed_sigma_mps: float = Field(0.05, ge=0)
    odom_yaw_rate_sigma_radps: float = Field(0.02, ge=0)
    odom_turn_sigma_rad: float = Field(
        0.0,
        ge=0,
        le=1.0,
        description="odometry heading error per square root of "
        "the angle turned (rad/sqrt(rad)): wheels that slip in turns. Replays only "
        "(calibrated); the simulated world makes no such error",
    )
    odom_travel_sigma_m: float = Field(
        0.0,
        ge=0,
        le=1.0,
        description="odometry along-track error per square root of "
        "the distance travelled (m/sqrt(m)). Replays only, as above",
    )
    speed_walk_mps_rtsec: float = Field(
        0.2,
        ge=0,
        le=100,
        description="how fast the vehicle's true speed may wander from its latest sample once the next is "
        "overdue (late, lost or silent): a random walk from the due time, per square root of a second",
    )
    yaw_rate_walk_radps_rtsec: float = Field(
        0.2,
        ge=0,
        le=100,
        description="the same for its turn rate (the default world's turning vehicles: 0.20-0.23; "
        "docs/decisions/realtime-restart.md)",
    )
    gnss_rate_hz: float = Field(5.0, gt=0, le=100)
    gnss_phase: float = Field(
        0.0,
        ge=0,
        lt=1,
        description="where in its period a GNSS fix comes, as a share of the period: fixes at "
        "(k + phase) / gnss_rate_hz, to the nearest IMU step (0: with the ranging epochs at equal rates; "
        "0.5 takes the fixes off the epochs, where a realtime swarm's work gathers: docs/benchmarks.md)",
    )
    gnss_sigma_m: float = Field(1.5, gt=0)
    gnss_correlated_sigma_m: float = Field(
        0.0,
        ge=0,
        description="of gnss_sigma_m, the part that wanders slowly "
        "(per axis; 0: white). ekf and ukf then estimate it as two "
        "Gauss-Markov states; ekf-slam treats all of it as white",
    )
    gnss_correlation_s: float = Field(60.0, gt=0, le=1e5, description="correlation time of that part")
    truth_rate_hz: float = Field(50.0, gt=0, le=1000)
    ranging_rate_hz: float = Field(5.0, gt=0, le=100, description="vehicle-to-vehicle radio ranging")
    ranging_max_m: float = Field(150.0, ge=0, description="ranging reaches vehicles this close (0: no ranging)")
    ranging_max_peers: int = Field(4, ge=0, le=249, description="the radio ranges at most this many peers, the nearest")
    range_sigma_m: float = Field(0.3, gt=0)
    bearing_sigma_rad: float = Field(0.02, gt=0)
    range_correlated_sigma_per_m: float = Field(
        0.0,
        ge=0,
        le=0.5,
        description="of a camera's landmark range "
        "error, the part that persists in time, per metre of range "
        "(0.03: 3 %; 0: white). known-map estimates it per landmark",
    )
    range_correlation_s: float = Field(5.0, gt=0, le=1e4, description="correlation time of that part")
    bearing_correlated_fraction: float = Field(
        0.0,
        ge=0,
        le=0.95,
        description="of a camera's landmark bearing "
        "error variance, the part that persists in time (0: white); "
        "known-map and slam estimate it per landmark",
    )
    bearing_correlation_s: float = Field(5.0, gt=0, le=1e4, description="correlation time of that part")
    range_scale_prior_sigma: float = Field(
        0.0,
        ge=0,
        le=0.5,
        description="how far a camera's range scale may "
        "be off (0.05: 5 %, every landmark read that much long or short); "
        "known-map then estimates it (0: taken as exact)",
    )
    odom_scale_prior_sigma: float = Field(
        0.0,
        ge=0,
        le=0.5,
        description="how far the wheel odometry's speed "
        "and yaw-rate scales may be off (0.1: 10 %); ekf, known-map and "
        "ekf-slam then estimate both (0: taken as exact)",
    )
    prior_sigma_m: float = Field(0.5, gt=0, description="launch-pad survey of the start position")
    unmodelled_sigma_m: float = Field(
        0.0,
        ge=0,
        le=10,
        description="how far, per axis, a replayed robot may lie from where its filter puts it beyond the "
        "filter's own covariance (what no sighting sees, what a calibration cannot know): added to the "
        "published position covariance, not to the filter's own (measured out of sample by the "
        "calibration, launch.unmodelled; the simulated world has no such error)",
    )
    prior_heading_sigma_rad: float = Field(0.05, gt=0)
    camera_rate_hz: float = Field(0.0, ge=0, le=100, description="down-looking camera frames (0: no camera)")
    camera_size_px: int = Field(80, ge=16, le=1024, description="square frame side (the paper's 80 px)")
    camera_noise_grey: float = Field(2.0, ge=0, le=100, description="pixel noise, grey levels (world)")
    keypoint_sigma_px: float = Field(0.7, gt=0, le=20, description="keypoint position noise the filter assumes")

    @model_validator(mode="after")
    def _correlated_part_is_a_part(self) -> _BuiltInSensors:
        if self.gnss_correlated_sigma_m >= self.gnss_sigma_m:
            raise ValueError(
                f"gnss_correlated_sigma_m ({self.gnss_correlated_sigma_m} m) must be below "
                f"gnss_sigma_m ({self.gnss_sigma_m} m): it is a part of the total"
            )
        return self


# the datasheet: the built-in sensors' fields, and a section per sensor added by the recipe (bus.sensors:
# ``sensors.<topic>``, each off until its ``rate_hz`` is set)
SensorSpec = create_model(
    "SensorSpec",
    __base__=_BuiltInSensors,
    __module__=__name__,
    __doc__=(
        "Rates and noise of the simulated sensors (also the vehicles' datasheet noise model): the built-in "
        "sensors' fields and a section per sensor added by the recipe (bus.sensors)."
    ),
    **{
        sensor.topic: (sensor.Spec, Field(default_factory=sensor.Spec, description=f"the {sensor.topic} (bus.sensors)"))
        for sensor in SENSORS
    },
)


class SensorTruth(_Strict):
    """How the world really is next to the datasheet (``sensors``), which is all the vehicles are
    told. The defaults are the idealized world (the filters' own models); ``HONEST_WORLD`` is a
    world richer than any filter: finer truth steps with inputs that vary inside a step, wheel scale
    error and slip, a time-correlated GNSS error with outliers, heavy-tailed noise."""

    gnss_sigma_factor: float = Field(1.0, gt=0, le=100, description="true GNSS white noise / datasheet")
    range_sigma_factor: float = Field(1.0, gt=0, le=100, description="true ranging noise / datasheet")
    substeps: int = Field(1, ge=1, le=100, description="truth integrated at the IMU period / substeps")
    wobble_speed_mps: float = Field(
        0.0,
        ge=0,
        le=10,
        description="RMS of a smooth speed variation (0.05-1.5 Hz) "
        "on top of the trajectory's law, varying inside a step",
    )
    wobble_yaw_rate_radps: float = Field(0.0, ge=0, le=2, description="RMS of the same for the yaw rate")
    odom_scale_sigma: float = Field(
        0.0, ge=0, le=0.5, description="spread of each vehicle's constant wheel scale error (0.01: 1 %)"
    )
    odom_slip_rate_hz: float = Field(0.0, ge=0, le=10, description="wheel slip episodes per second")
    odom_slip_s: float = Field(0.5, gt=0, le=60, description="length of a slip episode")
    odom_slip_fraction: float = Field(0.2, ge=-1, le=5, description="odometry reads speed x (1 + this) while slipping")
    gnss_walk_sigma_m: float = Field(
        0.0,
        ge=0,
        le=100,
        description="time-correlated GNSS error per axis: stationary sigma of a first-order Gauss-Markov process",
    )
    gnss_walk_tau_s: float = Field(60.0, gt=0, le=1e5, description="its correlation time")
    gnss_outlier_probability: float = Field(0.0, ge=0, le=1, description="share of fixes that are outliers")
    gnss_outlier_m: float = Field(20.0, ge=0, le=1e4, description="typical outlier size (0.5-1.5 x this)")
    heavy_tail_dof: float = Field(
        0.0,
        ge=0,
        le=1000,
        description="0: Gaussian white noise; > 2: Student-t "
        "with this many degrees of freedom and the same sigma (odometry, GNSS, ranging)",
    )

    @model_validator(mode="after")
    def _tail_has_a_variance(self) -> SensorTruth:
        if 0 < self.heavy_tail_dof <= 2:
            raise ValueError("heavy_tail_dof must be 0 (Gaussian) or above 2 (a Student-t with a variance)")
        return self


# A world richer than the filters (`swarm experiment cooperative`, the staged tests), so that a filter
# consistent in it is consistent for its own reasons, not because the world shares its model: the
# datasheet's GNSS sigma (1.5 m) is split into 1.2 m white and 0.9 m Gauss-Markov (60 s), so the total
# matches the datasheet but half of it no longer averages out.
HONEST_WORLD = {
    "gnss_sigma_factor": 0.8,
    "substeps": 5,
    "wobble_speed_mps": 0.2,
    "wobble_yaw_rate_radps": 0.03,
    "odom_scale_sigma": 0.005,
    "odom_slip_rate_hz": 0.02,
    "gnss_walk_sigma_m": 0.9,
    "gnss_walk_tau_s": 60.0,
    "gnss_outlier_probability": 0.002,
    "heavy_tail_dof": 5.0,
}
# What the filters are told in that world (the datasheet, rounded: the world's Gauss-Markov part is
# 0.9 m over 60 s, the datasheet says 1 m and a minute).
HONEST_DATASHEET = {"gnss_correlated_sigma_m": 1.0, "gnss_correlation_s": 60.0}
