"""Loop statistics (the p99 of the last window of samples, as numpy's percentile gives it) and the
realtime loop's phases."""

import numpy as np
import pytest

from vehicle.process.loop_stats import LoopStats


@pytest.mark.parametrize("count", [1, 2, 3, 99, 100, 101, 250, 1000])
def test_p99_is_numpys_linear_percentile_of_the_window(count):
    rng = np.random.default_rng(count)
    jitter, cycle = rng.exponential(300.0, count), rng.normal(100.0, 20.0, count)
    stats = LoopStats(window=200)
    for j, c in zip(jitter, cycle):
        stats.record(jitter_us=float(j), cycle_us=float(c), overran=bool(c > 140.0))
    window = slice(max(0, count - 200), count)  # the ring keeps the last 200 (order does not matter)
    assert stats.jitter_p99_us() == pytest.approx(np.percentile(jitter[window], 99), rel=1e-12)
    assert stats.cycle_p99_us() == pytest.approx(np.percentile(cycle[window], 99), rel=1e-12)
    assert stats.cycles == count and stats.overruns == int(np.sum(cycle > 140.0))


def test_no_samples_give_zero():
    assert LoopStats().jitter_p99_us() == 0.0 and LoopStats().cycle_p99_us() == 0.0


def test_realtime_vehicles_take_distinct_phases_spread_over_the_period():
    """Each vehicle cycles at its own phase after the world's tick, inside the period, none at the
    tick itself (where the world publishes) and no two together."""
    from vehicle.process.loops import schedule_phase_s

    for vehicles in (1, 2, 5, 32):
        phases = sorted(schedule_phase_s(v, vehicles, 0.02) for v in range(1, vehicles + 1))
        assert 0.0 < phases[0] and phases[-1] < 0.02
        gaps = np.diff([0.0, *phases, 0.02])
        assert np.allclose(gaps, 0.02 / (vehicles + 1))
