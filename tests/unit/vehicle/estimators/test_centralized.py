"""The centralized reference (vehicle.estimators.centralized): with no ranging it is every vehicle's own EKF side
by side (same motion, same fixes, zero cross-covariances), with ranging it stays consistent while
GNSS holds; in the jammed swarm of stage 4 it is the accuracy yardstick (test_cooperative_stages)."""

import numpy as np
import pytest

from bus.config import HONEST_DATASHEET, HONEST_WORLD, build_config
from experiments.centralized_reference import run_centralized
from experiments.harness import pose_nees_series

pytestmark = pytest.mark.monte_carlo


@pytest.mark.parametrize("datasheet", [{}, HONEST_DATASHEET], ids=["white-gnss", "gnss-error-states"])
def test_without_ranging_it_is_each_vehicles_own_ekf(datasheet):
    """Vehicle 1 of a 1-vehicle world: the joint filter and the vehicle EKF, fed the same samples
    (also with the GNSS error states, in the honest world that needs them)."""
    world = {"sensor_truth": HONEST_WORLD} if datasheet else {}
    config = build_config(
        {
            "world": {"vehicles": 1, "seed": 4, "trajectories": ["waypoints"], **world},
            "clock": {"duration_s": 20},
            "sensors": {"ranging_max_m": 0.0, **datasheet},
        }
    )
    central = run_centralized(config, score_every_us=1_000_000)[1]
    nees, errors = pose_nees_series(
        4, duration_s=20.0, trajectory="waypoints", world=world or None, estimator_spec=config.sensors
    )
    np.testing.assert_allclose(central["error_m"], errors, atol=1e-9)
    np.testing.assert_allclose(central["nees"], nees, rtol=1e-6)


def test_with_ranging_and_gnss_its_nees_is_consistent():
    """12 seeds of 4 vehicles with GNSS and ranging: the 95% interval of the ANEES (from the per-seed
    means; the vehicles of one swarm are correlated) holds 3 and is tight enough to mean it
    (measured 2.97 +- 0.53)."""
    per_seed = []
    for seed in range(1, 13):
        config = build_config({"world": {"vehicles": 4, "seed": seed}, "clock": {"duration_s": 25}})
        tracks = run_centralized(config, score_every_us=1_000_000).values()
        per_seed.append(np.mean([t["nees"][t["t_s"] >= 10.0].mean() for t in tracks]))
    mean, half = np.mean(per_seed), 1.96 * np.std(per_seed, ddof=1) / np.sqrt(len(per_seed))
    assert mean - half <= 3.0 <= mean + half and half < 1.0, (mean, half)
