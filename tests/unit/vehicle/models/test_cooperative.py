"""Cooperative localization: the Covariance Intersection update stays consistent when the
neighbour's estimate shares our errors (where a plain EKF update becomes over-confident), chooses its
weight on the pose it observes, skips fixes that bring nothing and leaves unobserved states alone; in
a swarm a vehicle whose GNSS is jammed stays localized through its neighbours, unless its radio is
jammed too."""

import numpy as np
import pytest
from scipy.stats import chi2

from bus.config import build_config
from experiments.harness import swarm_in_memory
from vehicle.models.cooperative import WEIGHT_GRID, CooperativeRule, cooperative_update
from vehicle.models.cooperative_fixes import CooperativeFix, SeenFix, relative_model, with_persisting_errors
from vehicle.models.landmarks import apply_correction_in_place

pytestmark = pytest.mark.monte_carlo


RUNS = 3000
P = np.diag([1.0, 1.0, 0.01, 1e-6])
R = np.diag([0.09, 0.0004])
TRUTH = np.array([0.0, 0.0, 0.3, 0.0])
NEIGHBOUR = np.array([30.0, 10.0])
RULES = [CooperativeRule(f, w) for f in ("split-ci", "ci", "paper") for w in ("optimal", "closed-form")]


def _anees(shared: float, rule: CooperativeRule, seed: int = 1) -> float:
    """Average pose NEES after one update when a share of the neighbour's position error is our own
    error (data incest); the prior and the neighbour each have covariance P[:2, :2]."""
    rng = np.random.default_rng(seed)
    errors, owns = rng.multivariate_normal(np.zeros(4), P, RUNS), rng.multivariate_normal(np.zeros(2), P[:2, :2], RUNS)
    noises = rng.multivariate_normal(np.zeros(2), R, RUNS)
    h, _, _ = relative_model(TRUTH, NEIGHBOUR)
    nees = []
    for e, own, noise in zip(errors, owns, noises):
        neighbour = NEIGHBOUR + shared * e[:2] + np.sqrt(1 - shared**2) * own
        z = h + noise
        fix = CooperativeFix(1, 0, 0, 2, z[0], z[1], R, neighbour, P[:2, :2])
        x_new, P_new, _ = cooperative_update(TRUTH + e, P, fix, 1e9, rule)
        d = (x_new - TRUTH)[:3]
        nees.append(float(d @ np.linalg.solve(P_new[:3, :3], d)))
    return float(np.mean(nees))


def test_covariance_intersection_stays_consistent_where_the_plain_update_does_not():
    upper = chi2.ppf(0.975, 3 * RUNS) / RUNS  # two-sided 95% band of the average of RUNS 3-dof NEES
    naive = CooperativeRule("naive")
    assert _anees(0.0, naive) < upper  # control: with independent errors the plain update is fine
    assert _anees(1.0, naive) > upper  # data incest: the plain update is over-confident
    for rule in RULES:
        assert _anees(1.0, rule) < upper and _anees(0.0, rule) < upper, rule


@pytest.mark.parametrize("fusion", ["split-ci", "ci"])
def test_the_weight_maximises_the_fused_information_and_one_means_do_not_fuse(fusion):
    """Brute force over w in [0, 1] (w = 1: own estimate alone) of det of the fused information about
    the measured [range, bearing], written out as CI of own M and the fix (split: R kept whole)."""
    rule, rng = CooperativeRule(fusion), np.random.default_rng(4)
    chose_one = 0
    for _ in range(300):
        L = rng.normal(size=(2, 2)) * rng.uniform(0.01, 3.0, size=2)
        M = L @ L.T + 1e-6 * np.eye(2)
        R, S = np.diag([rng.uniform(0.01, 1.0), rng.uniform(1e-4, 1e-2)]), np.diag(rng.uniform(0, 4, 2))

        def information(w):
            own = w * np.linalg.inv(M)
            if w == 1.0:
                return own
            fix = np.linalg.inv(R + S / (1 - w)) if fusion == "split-ci" else (1 - w) * np.linalg.inv(R + S)
            return own + fix

        scores = [np.linalg.det(information(w)) for w in WEIGHT_GRID]
        w = rule.choose_weight(M, R, S)
        chose_one += w == 1.0
        assert np.isclose(scores[int(np.flatnonzero(np.isclose(WEIGHT_GRID, w))[0])], max(scores), rtol=1e-9)
    assert chose_one > 0  # some draws have a fix worth nothing next to our own estimate


def test_a_fix_that_brings_nothing_leaves_a_good_estimate_alone():
    """Own position known to 0.1 m, the neighbour's to 10 m: w = 1, nothing changes (plain CI on the
    old grid inflated the covariance, heading and gyro bias included, at every such fix)."""
    P_good = np.diag([0.01, 0.01, 1e-4, 1e-6])
    fix = CooperativeFix(1, 0, 0, 2, 31.7, 0.02, R, NEIGHBOUR, np.eye(2) * 100.0)
    for rule in (CooperativeRule("split-ci"), CooperativeRule("ci")):
        x_new, P_new, result = cooperative_update(TRUTH, P_good, fix, 1e9, rule)
        assert result.accepted and x_new is TRUTH and P_new is P_good


def test_states_the_fix_does_not_observe_are_left_alone():
    """A gyro bias uncorrelated with the pose keeps its variance and value; one correlated with the
    heading follows it (its regression), and the joint covariance stays positive definite."""
    fix = CooperativeFix(1, 0, 0, 2, 31.0, 0.05, R, NEIGHBOUR, np.eye(2) * 0.2)
    x0 = np.array([0.0, 0.0, 0.3, 0.004])
    x_new, P_new, _ = cooperative_update(x0, P, fix, 1e9)
    assert x_new[3] == x0[3] and P_new[3, 3] == P[3, 3] and not np.allclose(P_new[:3, :3], P[:3, :3])
    correlated = P.copy()
    correlated[2, 3] = correlated[3, 2] = 0.8 * np.sqrt(P[2, 2] * P[3, 3])
    x_new, P_new, _ = cooperative_update(x0, correlated, fix, 1e9)
    assert x_new[3] != x0[3] and P_new[3, 3] < correlated[3, 3]
    assert np.linalg.eigvalsh(P_new).min() > 0


def test_split_ci_keeps_the_radio_noise_whole_and_fuses_tighter_than_plain_ci():
    fix = CooperativeFix(1, 0, 0, 2, 31.0, 0.05, R, NEIGHBOUR, np.eye(2) * 2.0)  # an interior weight
    _, P_split, _ = cooperative_update(TRUTH, P, fix, 1e9, CooperativeRule("split-ci"))
    _, P_plain, _ = cooperative_update(TRUTH, P, fix, 1e9, CooperativeRule("ci"))
    assert np.linalg.det(P_split[:3, :3]) < np.linalg.det(P_plain[:3, :3]) < np.linalg.det(P[:3, :3])


OBSERVER = np.array([30.0, 10.0, -2.5])  # the neighbour that sights us: x m, y m, heading rad
OBSERVER_P = np.diag([0.2, 0.2, 2e-4])


def _seen_fix(x_own: np.ndarray, observer: np.ndarray, noise: np.ndarray | None = None) -> SeenFix:
    """The sighting the observer at OBSERVER takes of a vehicle at ``x_own`` (3,), with ``noise`` (2,)
    (a draw of R) added when given, paired with the observer's broadcast pose ``observer`` (3,)."""
    dx, dy = x_own[:2] - OBSERVER[:2]
    z = np.array([np.hypot(dx, dy), np.arctan2(dy, dx) - OBSERVER[2]])
    if noise is not None:
        z = z + noise
    return SeenFix(1, 0, 0, 2, z[0], z[1], R, observer, OBSERVER_P)


def test_a_relayed_sighting_linearizes_its_own_model():
    """H is the derivative of the predicted [range, bearing] with respect to own pose (none on own
    heading: the bearing is the observer's), S = H_o P_o H_o^T with H_o the derivative with respect
    to the observer's pose; the paper's implied position is where the sighting puts us."""
    x = np.array([2.0, -1.0, 0.7, 0.0])
    fix = _seen_fix(x[:3], OBSERVER)
    y, H, R_sym, S = fix.linearized(x)
    step = 1e-6
    numeric = np.column_stack(
        [(fix.predicted(x[:3] + step * e) - fix.predicted(x[:3] - step * e)) / (2 * step) for e in np.eye(3)]
    )
    assert np.allclose(H, numeric, atol=1e-7) and np.allclose(y, 0.0, atol=1e-12)

    def seen_from(observer: np.ndarray) -> np.ndarray:
        return SeenFix(1, 0, 0, 2, 0.0, 0.0, R, observer, OBSERVER_P).predicted(x[:3])

    H_o = np.column_stack(
        [(seen_from(OBSERVER + step * e) - seen_from(OBSERVER - step * e)) / (2 * step) for e in np.eye(3)]
    )
    S_expected = H_o @ OBSERVER_P @ H_o.T
    assert np.allclose([S_expected[0, 0], S_expected[0, 1], S_expected[1, 1]], S, rtol=1e-6)
    assert np.allclose([R_sym[0], R_sym[2]], np.diag(R))
    innovation, H_paper, _, _ = fix.implied(x, OBSERVER_P)
    assert np.allclose(innovation, 0.0, atol=1e-9) and np.allclose(H_paper, np.eye(2, 3))


@pytest.mark.parametrize("relayed", [False, True])
def test_persisting_errors_enter_a_sighting_as_states(relayed):
    """With the range error s, bearing error b and camera range scale k of the sighting as states
    (range r (1 + k + s), bearing beta + b): the innovation is against the stretched prediction, H
    over [x, y, theta, s, b, k] is its derivative, R keeps its white part, and cov(x, z) runs through
    the error states."""
    x = np.array([2.0, -1.0, 0.7, 0.0, 0.03, -0.01, 0.02])  # pose, gyro bias, s, b, k
    fix = (
        _seen_fix(x[:3], OBSERVER)
        if relayed
        else CooperativeFix(1, 0, 0, 2, 5.0, 0.2, R, NEIGHBOUR, np.diag([0.04, 0.04]))
    )
    errors = {
        "range_state": 4,
        "range_sigma_per_m": 0.03,
        "bearing_state": 5,
        "bearing_var": 0.5 * R[1, 1],
        "scale_state": 6,
    }
    y, H, R_white, idx = with_persisting_errors(x, fix, *fix.linearized(x)[:2], fix.linearized(x)[2], errors)
    assert idx == [0, 1, 2, 4, 5, 6]

    def stretched(state: np.ndarray) -> np.ndarray:
        plain = fix.predicted(state[:3])
        return np.array([plain[0] * (1.0 + state[4] + state[6]), plain[1] + state[5]])

    expected = stretched(x)
    assert np.allclose(y, [fix.range_m - expected[0], fix.bearing_rad - expected[1]], atol=1e-12)
    step = 1e-6
    numeric = np.column_stack([(stretched(x + step * e) - stretched(x - step * e)) / (2 * step) for e in np.eye(7)])
    assert np.allclose(H, numeric[:, idx], atol=1e-6)
    r = fix.range_m - fix.linearized(x)[0][0]
    assert np.allclose(R_white, (max(R[0, 0] - (0.03 * r) ** 2, 0.1 * R[0, 0]), 0.0, 0.5 * R[1, 1]))  # white floor
    P_full = np.diag([0.5, 0.5, 0.01, 1e-6, 0.03**2, 0.5 * R[1, 1], 0.05**2])
    _, M, C, _, _, cov_xz = CooperativeRule().measurement(x, P_full, fix, False, errors)
    assert np.allclose(cov_xz, P_full[:, idx] @ H.T) and np.allclose(
        M, (lambda A: (A[0, 0], A[0, 1], A[1, 1]))(H @ P_full[np.ix_(idx, idx)] @ H.T)
    )


def _seen_anees(shared: bool, rule: CooperativeRule, seed: int = 2) -> float:
    """Average pose NEES after one relayed sighting. ``shared``: the observer's whole position error
    is also part of ours (the rest of ours independent), each estimate still true to its covariance."""
    rng = np.random.default_rng(seed)
    errors = rng.multivariate_normal(np.zeros(4), P, RUNS)
    observer_errors = rng.multivariate_normal(np.zeros(3), OBSERVER_P, RUNS)
    if shared:
        rest = rng.multivariate_normal(np.zeros(2), P[:2, :2] - OBSERVER_P[:2, :2], RUNS)
        errors[:, :2] = observer_errors[:, :2] + rest
    noises = rng.multivariate_normal(np.zeros(2), R, RUNS)
    nees = []
    for e, observer_error, noise in zip(errors, observer_errors, noises):
        fix = _seen_fix(TRUTH[:3], OBSERVER + observer_error, noise)
        x_new, P_new, _ = cooperative_update(TRUTH + e, P, fix, 1e9, rule)
        d = (x_new - TRUTH)[:3]
        nees.append(float(d @ np.linalg.solve(P_new[:3, :3], d)))
    return float(np.mean(nees))


def test_a_relayed_sighting_is_consistent_and_ci_covers_shared_errors():
    """With independent errors the plain update of a relayed sighting is consistent (ANEES inside the
    two-sided band: the model and S are right; leaving out the observer's heading takes it above the
    band); with the observer's position error part of our own, it becomes over-confident and every
    CI rule stays below the band's top."""
    lower, upper = chi2.ppf(0.025, 3 * RUNS) / RUNS, chi2.ppf(0.975, 3 * RUNS) / RUNS
    naive = CooperativeRule("naive")
    assert lower < _seen_anees(False, naive) < upper
    assert _seen_anees(True, naive) > upper
    for rule in RULES:
        assert _seen_anees(True, rule) < upper and _seen_anees(False, rule) < upper, rule


def test_the_in_place_update_of_a_slam_state_equals_the_dense_one():
    """A SLAM vehicle's update (three rank-1 updates on P's memory) gives the dense update's state
    and covariance, and the same gating."""
    rng = np.random.default_rng(5)
    n = 4 + 2 * 40
    A = rng.normal(size=(n, n)) * 0.1
    P_big = A @ A.T + np.eye(n) * 0.05
    x = np.concatenate([[1.0, 2.0, 0.3, 0.001], rng.uniform(-20, 20, 2 * 40)])
    rule = CooperativeRule()
    for offset in (0.2, 40.0):  # fused, then gated out
        fix = CooperativeFix(1, 0, 0, 2, 25.0 + offset, 0.4, R, np.array([20.0, 16.0]), np.eye(2) * 0.5)
        x_dense, P_dense, dense = cooperative_update(x, P_big, fix, 13.8, rule)
        x_in, P_in = x.copy(), P_big.copy()
        correction, in_place = rule.fuse(x_in, P_in, fix, 13.8)
        if correction is not None:
            apply_correction_in_place(x_in, P_in, correction)
        assert in_place.accepted == dense.accepted and np.isclose(in_place.nis, dense.nis)
        assert np.allclose(x_in, x_dense, atol=1e-10) and np.allclose(P_in, P_dense, atol=1e-10)


SEEDS = (1, 2, 3)


def _jammed_vehicle_rmse(cooperative: bool, comms_jammed: bool) -> tuple[float, float]:
    """Vehicle 1's position RMSE while its GNSS is jammed (8-24 s), pooled over SEEDS, and the
    swarm's ANEES."""
    faults = [{"kind": "jam-gnss", "center_m": [0.0, 0.0], "radius_m": 40.0, "start_s": 8.0}]
    if comms_jammed:
        faults.append({"kind": "jam-comms", "center_m": [0.0, 0.0], "radius_m": 40.0, "start_s": 8.0})
    errors, nees = [], []
    for seed in SEEDS:
        config = build_config(
            {
                "world": {"vehicles": 3, "seed": seed},
                "clock": {"duration_s": 24},
                "vehicle": {"cooperation": {"enabled": cooperative}},
                "faults": faults,
            }
        )
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


def test_the_sensitivity_to_the_own_position_is_the_linearizations():
    """own_jacobian (floats, for the neighbour monitor) equals the position columns of the H the
    update linearizes with, for a fix of a neighbour and a neighbour's sighting of this vehicle."""
    x = np.array([1.0, 2.0, 0.3, 0.0])
    ranged = CooperativeFix(1, 0, 0, 2, 5.0, 0.1, np.eye(2), np.array([10.0, -5.0]), np.eye(2))
    seen = SeenFix(1, 0, 0, 2, 5.0, 0.1, np.eye(2), np.array([10.0, -5.0, 0.2]), np.eye(3))
    np.testing.assert_allclose(ranged.own_jacobian(x), relative_model(x, ranged.neighbour_xy_m)[1][:, :2])
    np.testing.assert_allclose(seen.own_jacobian(x), seen.linearized(x)[1][:, :2])
