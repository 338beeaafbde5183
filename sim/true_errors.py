"""What the world does that no filter models (``world.sensor_truth``: the honest world, richer than
any filter's model): inputs that vary inside a step, a wheel scale error and slip, a time-correlated
(Gauss-Markov) GNSS error with outliers, and Student-t white noise.

Each vehicle draws these from its own generator (never the one of its datasheet noise), in blocks
of the world's steps, so turning them on or off leaves every other noise stream bit-identical, and
with the defaults every function here returns its input unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bus.config import SensorTruth

WOBBLE_BAND_HZ = (0.05, 1.5)
WOBBLE_TONES = 3


def wobble_tones(truth: SensorTruth, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frequencies (2, tones) in Hz, phases (2, tones) in rad and amplitudes (2, 1) [m/s, rad/s] of the
    smooth input variation of one vehicle: rows speed, yaw rate; the sum has the configured RMS."""
    freq = rng.uniform(*WOBBLE_BAND_HZ, (2, WOBBLE_TONES))
    phase = rng.uniform(0.0, 2.0 * np.pi, (2, WOBBLE_TONES))
    rms = np.array([[truth.wobble_speed_mps], [truth.wobble_yaw_rate_radps]])
    return freq, phase, rms * np.sqrt(2.0 / WOBBLE_TONES)  # each tone's mean square is amplitude^2 / 2


def wobble(t_s: float | np.ndarray, freq: np.ndarray, phase: np.ndarray, amplitude: np.ndarray) -> np.ndarray:
    """Input variation (N, 2) [m/s, rad/s] at ``t_s`` for N vehicles' tones (N, 2, tones), amplitudes
    (N, 2, 1); at times ``t_s`` of shape (..., 1, 1), (..., N, 2)."""
    t_s = np.asarray(t_s)[..., None]  # against the tones' axis
    return np.sum(amplitude * np.sin(2.0 * np.pi * freq * t_s + phase), axis=-1)


def student_scale(dof: float, rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    """Factors that turn unit-variance Gaussian samples into Student-t samples of ``dof`` degrees of
    freedom with the same variance: sqrt((dof - 2) / chi2(dof)). Ones when ``dof`` is 0."""
    if not dof:
        return np.ones(shape)
    return np.sqrt((dof - 2.0) / rng.chisquare(dof, shape))


@dataclass
class TrueErrors:
    """One vehicle's hidden errors: see the module docstring."""

    truth: SensorTruth
    rng: np.random.Generator
    odom_scale: float
    gnss_walk_m: np.ndarray  # (2,) current Gauss-Markov GNSS error
    block: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def draw(cls, truth: SensorTruth, rng: np.random.Generator) -> TrueErrors:
        return cls(
            truth, rng, float(rng.normal(0.0, truth.odom_scale_sigma)), rng.normal(0.0, truth.gnss_walk_sigma_m, 2)
        )

    def draw_block(self, steps: int, vehicles: int) -> None:
        """Draw the next ``steps`` steps (:meth:`next_block`) and use them from now on."""
        self.block = self.next_block(steps, vehicles)

    def next_block(self, steps: int, vehicles: int) -> dict[str, np.ndarray]:
        """The next ``steps`` steps' draws (the same number whatever is used or silenced)."""
        rng, dof = self.rng, self.truth.heavy_tail_dof
        return {
            "walk": rng.normal(0.0, 1.0, (steps, 2)),
            "outlier": rng.random(steps),
            "outlier_dir": rng.uniform(0.0, 2.0 * np.pi, steps),
            "outlier_size": rng.uniform(0.5, 1.5, steps),
            "slip": rng.random(steps),
            "tail_odom": student_scale(dof, rng, (steps,)),
            "tail_gnss": student_scale(dof, rng, (steps,)),
            "tail_ranging": student_scale(dof, rng, (steps, vehicles)),
        }

    def gnss_error(self, k: int, period_s: float, noise: np.ndarray) -> np.ndarray:
        """The fix's error (2,) in m at step ``k`` (called once per GNSS period, silenced or not):
        white noise (heavy-tailed), the Gauss-Markov part moved on by one period, and an outlier now and then."""
        truth = self.truth
        a = np.exp(-period_s / truth.gnss_walk_tau_s)
        self.gnss_walk_m = a * self.gnss_walk_m + np.sqrt(1.0 - a * a) * truth.gnss_walk_sigma_m * self.block["walk"][k]
        error = noise * self.block["tail_gnss"][k] + self.gnss_walk_m
        if self.block["outlier"][k] < truth.gnss_outlier_probability:
            angle = self.block["outlier_dir"][k]
            error = error + truth.gnss_outlier_m * self.block["outlier_size"][k] * np.array(
                [np.cos(angle), np.sin(angle)]
            )
        return error


def odometry_rows(
    truth: SensorTruth,
    t_us: int,
    period_s: float,
    speed_mps: np.ndarray,
    yaw_rate_radps: np.ndarray,
    noise: np.ndarray,
    draws: OdometryDraws,
    slip_until_us: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The wheel odometry rows [speed m/s, yaw rate rad/s] (N, 2) of N vehicles at ``t_us`` for their
    true inputs (N,) and the datasheet's white noise (N, 2): scaled, slipping, heavy-tailed; and when
    each vehicle's slip ends (N,) us after this step (a slip starts where the step's draw is below
    ``odom_slip_rate_hz`` x ``period_s`` and lasts ``odom_slip_s``)."""
    starts = draws.slip < truth.odom_slip_rate_hz * period_s
    slip_until_us = np.where(starts, t_us + round(truth.odom_slip_s * 1e6), slip_until_us)
    slip = np.where(t_us < slip_until_us, 1.0 + truth.odom_slip_fraction, 1.0)
    rows = np.empty((len(speed_mps), 2))
    rows[:, 0] = speed_mps * (1.0 + draws.scale) * slip + noise[:, 0] * draws.tail
    rows[:, 1] = yaw_rate_radps + noise[:, 1] * draws.tail
    return rows, slip_until_us


@dataclass(frozen=True)
class OdometryDraws:
    """N vehicles' wheel scale errors (N,) and one step's slip draws and Student-t factors (N,)."""

    scale: np.ndarray
    slip: np.ndarray
    tail: np.ndarray
