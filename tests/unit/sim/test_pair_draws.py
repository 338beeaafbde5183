"""A large swarm's ranging noise is drawn per pair, on first use: what a vehicle costs does not grow
with the swarm, the draws have the datasheet's statistics, and faults still shift no stream."""

import numpy as np

from bus.config import build_config
from sim.pair_draws import PAIRWISE_FROM, PairDraws
from sim.world import World


def test_a_pair_draws_the_same_whatever_else_was_drawn_and_in_any_order():
    first, second = (
        PairDraws(7, 100, np.array([0.1, 0.02]), 1.0, 5.0),
        PairDraws(7, 100, np.array([0.1, 0.02]), 1.0, 5.0),
    )
    for peer in (3, 40, 200):
        first.of(peer)
    assert np.array_equal(first.of(40)[0], second.of(40)[0]) and np.array_equal(first.of(40)[1], second.of(40)[1])
    assert not np.array_equal(first.of(40)[0], first.of(41)[0])
    assert not np.array_equal(PairDraws(8, 100, np.array([0.1, 0.02]), 1.0, 5.0).of(40)[0], first.of(40)[0])


def test_the_pairs_have_the_datasheets_spread_and_unit_variance_tails():
    sigmas = np.array([0.1, 0.02])
    noise, tail = zip(*(PairDraws(11, 100, sigmas, 1.5, 5.0).of(j) for j in range(400)))
    noise, tail = np.concatenate(noise), np.concatenate(tail)  # 40,000 samples
    assert np.allclose(noise.std(axis=0), 1.5 * sigmas, rtol=0.03) and np.allclose(noise.mean(axis=0), 0, atol=0.01)
    assert abs(np.mean(tail**2) - 1.0) < 0.06  # Student-t factors of unit variance (5 dof: heavy, so loose)


def test_a_large_world_draws_only_the_pairs_in_reach_and_a_fault_shifts_nobody_elses_noise():
    vehicles = PAIRWISE_FROM + 5
    config = build_config({"world": {"vehicles": vehicles, "seed": 4}})
    blackout = [{"kind": "blackout", "vehicle": 1, "sensor": "ranging", "start_s": 0.0, "for_s": 2.0}]
    plain, faulted = World(config), World(build_config({**config.model_dump(mode="json"), "faults": blackout}))
    a, b = plain.advance(1_999_999), faulted.advance(1_999_999)
    assert not b.rows[1].get("ranging") and a.rows[1]["ranging"]
    for vid in range(2, vehicles + 1):
        assert [r[2].tolist() for r in a.rows[vid]["ranging"]] == [r[2].tolist() for r in b.rows[vid]["ranging"]]
    drawn = [len(v.noise["ranging"].draws._pairs) for v in plain.vehicles]
    assert max(drawn) <= 2 * config.sensors.ranging_max_peers  # in reach, not the swarm
