"""Each vehicle's noise, drawn from its own generators in blocks of ``BLOCK_STEPS`` world steps, so
that the world's output never depends on how time is cut into ticks and faults never shift the
noise streams. A vehicle's next block is drawn ahead, at a step of the current block of its own
(``draw_ahead_step``), so that the step at a block's start is not every vehicle's draws at once;
each generator gives the same draws in the same order either way."""

from __future__ import annotations

import numpy as np

from bus.config import SensorSpec, SensorTruth
from bus.topics import Topic
from sim.pair_draws import PAIRWISE_FROM, PairDraws
from sim.true_errors import TrueErrors

BLOCK_STEPS = 100


def draw_ahead_step(index: int, vehicles: int) -> int:
    """The step of every block at which vehicle ``index`` (0-based) of ``vehicles`` draws its next
    block: spread evenly over steps 1 to BLOCK_STEPS - 1 (step 0 of the first block draws the
    vehicles' priors from the same generators, after the block)."""
    return 1 + index * (BLOCK_STEPS - 1) // vehicles


def ahead_schedule(vehicles: int) -> dict[int, list[int]]:
    """Step of a block -> the indices of the vehicles that draw their next block then."""
    schedule: dict[int, list[int]] = {}
    for index in range(vehicles):
        schedule.setdefault(draw_ahead_step(index, vehicles), []).append(index)
    return schedule


def next_block(
    spec: SensorSpec,
    truth: SensorTruth,
    step_us: int,
    vehicles: int,
    rng: np.random.Generator,
    ranging_rng: np.random.Generator,
    errors: TrueErrors,
) -> tuple[dict, dict]:
    """The next BLOCK_STEPS steps of every noise source of one vehicle of ``vehicles``, from its
    generators: (white noise by source, the true errors' draws)."""
    n = BLOCK_STEPS
    if vehicles >= PAIRWISE_FROM:  # per pair on first use: a vehicle costs its peers in reach, not the swarm
        sigmas = np.array([spec.range_sigma_m, spec.bearing_sigma_rad])
        key = int(ranging_rng.integers(2**63))
        pairs = PairDraws(key, n, sigmas, truth.range_sigma_factor, truth.heavy_tail_dof)
        noise = _white(spec, truth, step_us, rng, n) | {Topic.RANGING: pairs.noise()}
        return noise, errors.next_block(n, 0) | {"tail_ranging": pairs.tail()}
    ranging = ranging_rng.normal(0.0, [spec.range_sigma_m, spec.bearing_sigma_rad], (n, vehicles, 2))
    noise = _white(spec, truth, step_us, rng, n) | {Topic.RANGING: ranging * truth.range_sigma_factor}
    return noise, errors.next_block(n, vehicles)


def _white(spec: SensorSpec, truth: SensorTruth, step_us: int, rng: np.random.Generator, n: int) -> dict:
    """The white noise of every source but ranging, in ``next_block``'s order of draws."""
    return {
        "gyro": rng.normal(0.0, spec.gyro_sigma_radps, (n, 3)),
        "accel": rng.normal(0.0, spec.accel_sigma_mps2, (n, 3)),
        "walk": rng.normal(0.0, spec.gyro_bias_walk_radps_rtsec * np.sqrt(step_us * 1e-6), (n, 3)),
        Topic.ODOM: rng.normal(0.0, [spec.odom_speed_sigma_mps, spec.odom_yaw_rate_sigma_radps], (n, 2)),
        Topic.GNSS: rng.normal(0.0, spec.gnss_sigma_m, (n, 2)) * truth.gnss_sigma_factor,
    }
