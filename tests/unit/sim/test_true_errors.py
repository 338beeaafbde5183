"""The honest world's hidden errors (sim.true_errors, world.sensor_truth): each one does what its
setting says, measured on the world's own output, and the idealized defaults change nothing."""

import numpy as np

from bus.config import HONEST_WORLD, SensorTruth, build_config
from sim.true_errors import TrueErrors, student_scale
from sim.world import World


def _world(seconds: float, **truth) -> tuple[World, list]:
    world = World(
        build_config({"world": {"vehicles": 2, "seed": 7, "trajectories": ["waypoints"], "sensor_truth": truth}})
    )
    return world, [world.advance(round(t * 1e6)) for t in np.arange(1.0, seconds + 1.0)]


def _rows(outputs: list, topic: str, vid: int = 1) -> np.ndarray:
    return np.concatenate([out.blocks(vid)[topic][2] for out in outputs if topic in out.blocks(vid)])


def _truth(outputs: list) -> np.ndarray:
    return np.concatenate([np.array(out.truth) for out in outputs])


def test_gauss_markov_gnss_error_has_its_sigma_and_correlation_time():
    truth = SensorTruth(gnss_walk_sigma_m=0.9, gnss_walk_tau_s=10.0)
    errors = TrueErrors.draw(truth, np.random.default_rng(1))
    walk = []
    for _ in range(400):
        errors.draw_block(100, 1)
        walk += [errors.gnss_error(k, 0.2, np.zeros(2)) for k in range(100)]
    walk = np.array(walk)  # 40,000 fixes 0.2 s apart: 800 s, 80 correlation times
    assert 0.75 < walk.std() < 1.05
    lag = int(10.0 / 0.2)  # one correlation time: correlation 1/e
    rho = np.mean([np.corrcoef(walk[:-lag, a], walk[lag:, a])[0, 1] for a in (0, 1)])
    assert 0.2 < rho < 0.55, rho


def test_outliers_come_at_their_rate_and_size():
    truth = SensorTruth(gnss_outlier_probability=0.01, gnss_outlier_m=20.0)
    errors = TrueErrors.draw(truth, np.random.default_rng(2))
    sizes = []
    for _ in range(200):
        errors.draw_block(100, 1)
        sizes += [np.hypot(*errors.gnss_error(k, 0.2, np.zeros(2))) for k in range(100)]
    outliers = np.array(sizes)[np.array(sizes) > 0]
    assert 140 < len(outliers) < 260 and outliers.min() >= 10.0 and outliers.max() <= 30.0


def test_student_t_noise_keeps_the_variance_and_grows_the_tails():
    z = np.random.default_rng(3).normal(size=200_000) * student_scale(5.0, np.random.default_rng(4), (200_000,))
    assert abs(z.var() - 1.0) < 0.05
    assert np.mean(np.abs(z) > 4.0) > 20 * 6.3e-5  # Gaussian: 6.3e-5 beyond 4 sigma
    assert np.all(student_scale(0.0, np.random.default_rng(5), (3,)) == 1.0)


def test_wheel_odometry_has_a_scale_error_and_slips():
    world, outputs = _world(60.0, odom_scale_sigma=0.02, odom_slip_rate_hz=0.2, odom_slip_s=1.0, odom_slip_fraction=0.3)
    ideal_world, ideal = _world(60.0)
    ratio = _rows(outputs, "odom")[:, 0] / _rows(ideal, "odom")[:, 0]  # same white noise in both worlds
    scale = 1.0 + world.vehicles[0].errors.odom_scale
    slipping = np.isclose(ratio, scale * 1.3, atol=0.02)
    assert np.mean(np.isclose(ratio, scale, atol=0.02) | slipping) > 0.97
    assert 0.05 < slipping.mean() < 0.35  # about 0.2 episodes/s x 1 s


def test_inputs_vary_inside_a_step_and_truth_moves_by_substeps():
    """With a wobble the gyro's sample at a step no longer tells the turn over the step; constant
    inputs integrated in 5 substeps give the same arc as in one."""
    _, fine = _world(10.0, substeps=5)
    _, coarse = _world(10.0)
    np.testing.assert_allclose(_truth(fine), _truth(coarse), atol=1e-9)
    _, wobbly = _world(10.0, substeps=5, wobble_yaw_rate_radps=0.05)
    truth = _truth(wobbly)[:, 0]
    turned = np.diff(np.unwrap(truth[:, 2]))
    sampled = truth[:-1, 4] * 0.02  # truth rows at 50 Hz: yaw rate sampled at the start of each 20 ms
    assert np.max(np.abs(turned - sampled)) > 1e-5


def test_the_honest_world_keeps_the_datasheet_total_gnss_sigma():
    """1.2 m white and 0.9 m correlated: 1.5 m in all, the datasheet's sigma the vehicles are told."""
    truth, spec_sigma = SensorTruth(**HONEST_WORLD), 1.5
    total = np.hypot(truth.gnss_sigma_factor * spec_sigma, truth.gnss_walk_sigma_m)
    assert abs(total - spec_sigma) < 1e-9
