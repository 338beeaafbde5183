"""Cooperative localization: the Covariance Intersection update stays consistent when the
neighbour's estimate shares our errors (where a plain EKF update becomes over-confident), and in a
swarm a vehicle whose GNSS is jammed stays localized through its neighbours, unless its radio is
jammed too."""

import numpy as np
from scipy.stats import chi2

from bus.angles import wrap_angle
from bus.config import build_config
from tests.offline import swarm_in_memory
from vehicle.cooperative import WEIGHTS, CooperativeFix, ci_weight, cooperative_update, relative_model
from vehicle.ekf import gated_update

RUNS = 3000
P = np.diag([1.0, 1.0, 0.01, 1e-6])
R = np.diag([0.09, 0.0004])
TRUTH = np.array([0.0, 0.0, 0.3, 0.0])
NEIGHBOUR = np.array([30.0, 10.0])


def _anees(shared: float, seed: int = 1) -> tuple[float, float]:
    """Average pose NEES after one update, CI and plain EKF, when a share of the neighbour's position
    error is our own error (data incest)."""
    rng = np.random.default_rng(seed)
    nees_ci, nees_ekf = [], []
    for _ in range(RUNS):
        e = rng.multivariate_normal(np.zeros(4), P)
        x = TRUTH + e
        own = rng.multivariate_normal(np.zeros(2), P[:2, :2])
        neighbour = NEIGHBOUR + shared * e[:2] + np.sqrt(1 - shared**2) * own
        h, _, _ = relative_model(TRUTH, NEIGHBOUR)
        z = h + rng.multivariate_normal(np.zeros(2), R)
        fix = CooperativeFix(1, 0, 0, 2, z[0], z[1], R, neighbour, P[:2, :2])
        x_ci, P_ci, _ = cooperative_update(x, P, fix, gate=1e9)
        predicted, H, Hj = relative_model(x, neighbour)
        y = np.array([z[0] - predicted[0], wrap_angle(z[1] - predicted[1])])
        x_ekf, P_ekf, _ = gated_update(x, P, y, H, R + Hj @ P[:2, :2] @ Hj.T, gate=1e9)
        for out, (xx, PP) in ((nees_ci, (x_ci, P_ci)), (nees_ekf, (x_ekf, P_ekf))):
            d = (xx - TRUTH)[:3]
            out.append(float(d @ np.linalg.solve(PP[:3, :3], d)))
    return float(np.mean(nees_ci)), float(np.mean(nees_ekf))


def test_covariance_intersection_stays_consistent_where_the_plain_ekf_does_not():
    upper = chi2.ppf(0.975, 3 * RUNS) / RUNS  # two-sided 95% band of the average of RUNS 3-dof NEES
    ci_independent, ekf_independent = _anees(shared=0.0)
    ci_shared, ekf_shared = _anees(shared=1.0)
    assert ekf_independent < upper  # control: with independent errors the plain update is fine
    assert ekf_shared > upper       # data incest: the plain update is over-confident
    assert ci_shared < upper and ci_independent < upper


SEEDS = (1, 2, 3)


def _jammed_vehicle_rmse(cooperative: bool, comms_jammed: bool) -> tuple[float, float]:
    """Vehicle 1's position RMSE while its GNSS is jammed (8-24 s), pooled over SEEDS, and the
    swarm's ANEES."""
    faults = [{"kind": "jam-gnss", "center_m": [0.0, 0.0], "radius_m": 40.0, "start_s": 8.0}]
    if comms_jammed:
        faults.append({"kind": "jam-comms", "center_m": [0.0, 0.0], "radius_m": 40.0, "start_s": 8.0})
    errors, nees = [], []
    for seed in SEEDS:
        config = build_config({"world": {"vehicles": 3, "seed": seed}, "clock": {"duration_s": 24},
                               "vehicle": {"cooperative": cooperative}, "faults": faults})
        runs = swarm_in_memory(config)
        errors.append(runs[1]["error_m"][runs[1]["t_s"] >= 8.0])
        nees += [r["nees"] for r in runs.values()]
    return float(np.sqrt(np.mean(np.concatenate(errors) ** 2))), float(np.concatenate(nees).mean())


def test_neighbours_keep_a_gnss_jammed_vehicle_localized_unless_the_radio_is_jammed_too():
    alone, _ = _jammed_vehicle_rmse(cooperative=False, comms_jammed=False)
    helped, anees = _jammed_vehicle_rmse(cooperative=True, comms_jammed=False)
    cut_off, _ = _jammed_vehicle_rmse(cooperative=True, comms_jammed=True)
    assert helped < 0.5 and helped < alone / 4
    assert cut_off > 2 * helped
    assert anees < 3.0  # CI is conservative: never over-confident


def test_the_ci_weight_is_the_one_that_minimises_the_determinant():
    """The closed form (matrix determinant lemma) picks the weight brute force over det(P+) picks."""
    rng = np.random.default_rng(4)
    for _ in range(200):
        L = rng.normal(size=(4, 4)) * rng.uniform(0.01, 3.0, size=4)
        P = L @ L.T + 1e-6 * np.eye(4)
        x = np.append(rng.normal(size=3), 0.0)
        _, H, Hj = relative_model(x, rng.normal(scale=30.0, size=2))
        R = np.diag([rng.uniform(0.01, 1.0), rng.uniform(1e-4, 1e-2)]) + Hj @ np.eye(2) * rng.uniform(0, 4) @ Hj.T
        A, B = np.linalg.inv(P), H.T @ np.linalg.solve(R, H)
        dets = [np.linalg.det(w * A + (1 - w) * B) for w in WEIGHTS]
        best = WEIGHTS[int(np.argmax(dets))]
        w = ci_weight(P, H, R)
        # equal, or a near-tie in det (floating point picks either neighbour)
        assert w == best or np.isclose(max(dets), dets[int(np.flatnonzero(WEIGHTS == w)[0])], rtol=1e-9)


def test_the_in_place_ci_update_of_a_slam_state_equals_the_dense_one():
    """A SLAM vehicle's CI update (P scaled in place, rank-2 update on P's memory) gives the dense
    update's state and covariance, and the same gating."""
    from vehicle.cooperative import cooperative_update_in_place
    from vehicle.ekf_slam_core import update_in_place

    rng = np.random.default_rng(5)
    n = 4 + 2 * 40
    A = rng.normal(size=(n, n)) * 0.1
    P = A @ A.T + np.eye(n) * 0.05
    x = np.concatenate([[1.0, 2.0, 0.3, 0.001], rng.uniform(-20, 20, 2 * 40)])
    for offset in (0.2, 40.0):  # fused, then gated out
        fix = CooperativeFix(1, 0, 0, 2, 25.0 + offset, 0.4, np.diag([0.09, 4e-4]), np.array([20.0, 16.0]), np.eye(2) * 0.5)
        x_dense, P_dense, dense = cooperative_update(x, P, fix, 13.8)
        x_in, P_in = x.copy(), P.copy()
        in_place = cooperative_update_in_place(x_in, P_in, fix, 13.8, update_in_place)
        assert in_place.accepted == dense.accepted and np.isclose(in_place.nis, dense.nis)
        assert np.allclose(x_in, x_dense, atol=1e-10) and np.allclose(P_in, P_dense, atol=1e-10)


def test_naive_fusion_double_counts_and_turns_overconfident():
    """`cooperative_fusion = "naive"` (a plain Kalman update, the neighbour taken as independent) in
    a 4-vehicle swarm with GNSS jammed for everyone after 5 s: the vehicles fuse each other's
    estimates back and forth, and the swarm's NEES leaves the 95% band from above."""
    nees = []
    for seed in (1, 2, 3):
        config = build_config({"world": {"vehicles": 4, "seed": seed}, "clock": {"duration_s": 30},
                               "vehicle": {"cooperative_fusion": "naive"},
                               "faults": [{"kind": "jam-gnss", "center_m": [0.0, 0.0], "radius_m": 1000.0, "start_s": 5.0}]})
        nees += [r["nees"][r["t_s"] >= 10.0] for r in swarm_in_memory(config, sample_every_us=1_000_000).values()]
    per_step = np.array(nees).mean(axis=0)  # one sample per vehicle and seed at each second: independent
    upper = chi2.ppf(0.975, 3 * len(nees)) / len(nees)
    assert np.all(per_step > upper), (per_step, upper)
