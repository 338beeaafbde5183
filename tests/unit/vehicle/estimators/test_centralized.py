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


def _relative_nees(datasheet: dict, seed: int) -> tuple[float, int]:
    """Mean NEES of the relative part of the joint pose error (experiments.swarm_modes) over a
    4-vehicle swarm in the honest world (wheels 0.5 % off scale), GNSS jammed for 3 of them from 10 s."""
    from experiments.cooperative import Setup, cooperative_config

    data = cooperative_config("ci-ekf", seed, Setup(vehicles=4, jammed=3, jam_start_s=10.0, jam_s=40.0))
    config = build_config({**data.model_dump(mode="json"), "sensors": {**HONEST_DATASHEET, **datasheet}})
    modes = []
    run_centralized(config, score_every_us=1_000_000, modes=modes)
    return float(np.mean([m.relative_nees for _, m in modes])), modes[0][1].relative_dof


def test_told_the_wheels_scale_uncertainty_its_relative_geometry_is_honest():
    """The honest world's wheels read 0.5 % off scale per vehicle; a filter not told so over-trusts
    the geometry dead reckoning gives between its vehicles (relative NEES well above its dof); the
    EKF told the datasheet's scale uncertainty carries two scale states per vehicle and is honest."""
    for seed in (1, 2):
        blind, dof = _relative_nees({}, seed)
        told, _ = _relative_nees({"odom_scale_prior_sigma": 0.005}, seed)
        assert blind > 1.4 * dof and 0.5 * dof < told < 1.25 * dof, (seed, blind, told, dof)
