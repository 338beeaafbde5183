"""Held inputs (vehicle.inputs): the mean of a zero-order-held input over a propagation interval,
and the variance of that mean, which must count each sample's noise in full even when its hold
straddles propagation boundaries (an input at 15 ms integrated in 20 ms cycles)."""

import numpy as np

from vehicle.inputs import HeldInput


def test_mean_and_variance_factor_of_samples_inside_one_interval():
    held = HeldInput()
    held.restart(0)
    for k in range(4):  # four samples evenly spread over 20 ms
        held.sample(5000 * k, float(k))
    mean, factor = held.close(20_000)
    assert np.isclose(mean, 1.5) and np.isclose(factor, 0.25)


def _predicted_and_actual_variance(
    rng: np.random.Generator, input_us: int, cycle_us: int, runs: int = 4000
) -> tuple[float, float]:
    """Distance error variance (sigma 1 per sample) after 1 s: the sum of the per-cycle variances
    the filter would add, and the Monte Carlo variance of the integrated sample noise."""
    stamps = np.arange(0, 1_000_000, input_us)
    noise = rng.standard_normal((runs, len(stamps)))
    holds = np.diff(np.append(stamps, 1_000_000)) * 1e-6
    actual = float(np.var(noise @ holds))
    held, predicted, t = HeldInput(), 0.0, 0
    held.restart(0)
    pending = list(stamps)
    for end in range(cycle_us, 1_000_001, cycle_us):
        while pending and pending[0] < end:
            held.sample(int(pending.pop(0)), 0.0)
        _, factor = held.close(end)
        predicted += factor * ((end - t) * 1e-6) ** 2
        t = end
    return predicted, actual


def test_a_sample_held_across_cycles_counts_its_whole_variance():
    """Predicted / actual variance, measured: 1.01 (aligned), 0.995 (15 ms inputs in 20 ms cycles),
    1.03 (10 ms), 1.00 (30 ms); counting only each piece's own square gave 0.77 at 15 ms (a filter
    overconfident on its odometry: known-map's synthetic ANEES 3.5 against 3.0)."""
    rng = np.random.default_rng(3)
    for input_us, cycle_us in ((20_000, 20_000), (15_000, 20_000), (10_000, 20_000), (30_000, 20_000)):
        predicted, actual = _predicted_and_actual_variance(rng, input_us, cycle_us)
        assert 0.9 < predicted / actual < 1.1, (input_us, cycle_us, predicted / actual)
