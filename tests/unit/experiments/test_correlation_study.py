"""Kia, Rounds and Martinez's interim-master algorithm in the linear study (experiments.correlation_study):
with every broadcast delivered, each vehicle's covariance is the centralized filter's block for it
and its expected NEES is 3, on a ranging graph with a cycle; a vehicle that misses broadcasts keeps a
book the others no longer share, which the study reports as a breakdown instead of failing."""

import numpy as np

from experiments.correlation_study import Regime, study

TRIANGLE = (3, [(0, 1), (1, 2), (0, 2)])


def test_with_every_broadcast_delivered_it_is_the_centralized_filter_on_a_cycle():
    kia = study(*TRIANGLE, "kia", epochs=120, settle=40)
    central = study(*TRIANGLE, "centralized", epochs=120, settle=40)
    assert kia.broke_at is None
    assert kia.largest_gap < 1e-12
    np.testing.assert_allclose(kia.expected_nees, 3.0, atol=1e-9)
    assert abs(kia.rms_position_m - central.rms_position_m) < 1e-9
    assert kia.messages_per_epoch > 2.0  # each update goes to every other vehicle


def test_lost_broadcasts_leave_books_the_swarm_does_not_share():
    lossy = study(*TRIANGLE, "kia", Regime(loss=0.05, seed=0))
    assert lossy.largest_gap > 1e-3  # a vehicle that missed an update is no longer the centralized filter
    assert lossy.broke_at is not None  # and before 300 epochs some update's S is not a covariance
