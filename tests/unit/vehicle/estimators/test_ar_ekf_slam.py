"""ar-ekf-slam: the range state machine's transitions; the state stays bounded over a long run while
ekf-slam's grows; and over 50 seeded runs of the pure core (identified landmark sightings, no
camera), a pose RMSE within 1.3x of full EKF-SLAM on the same runs, its NEES inside the two-sided
95 % band with landmarks leaving the local map and coming back, and the naive re-entry (an old
marginal put back uncorrelated) over-confident on the same runs."""

import numpy as np
import pytest

from bus import messages as m
from bus import statistics
from bus.config import ArSlamConfig, build_config
from vehicle.estimators import ar_ekf_slam, ekf_slam
from vehicle.estimators.ar_ekf_slam import next_radius

SPEC = ArSlamConfig()
PERIOD_US = 20_000  # the vehicles' loop period (coarser cycles make EKF-SLAM itself over-confident)
# A range scaled to this small world (a circle of 8 m over a 3 m grid of landmarks): the local map
# holds 5-15 landmarks and R moves between 4 and 10 m, so landmarks leave it and come back each lap.
SMALL = {"r0_m": 8.0, "r_max_m": 10.0, "n_min": 5, "n_max": 15, "dr_m": 0.5}


@pytest.mark.parametrize(
    ("radius", "n", "expected"),
    [
        (25.0, 3, 25.1),  # q1: too few landmarks, room to grow
        (35.0, 3, 35.0),  # q1 at R_max: stays
        (25.0, 60, 24.9),  # q2: too many
        (36.0, 20, 35.9),  # q2: beyond R_max
        (25.0, 20, 25.0),  # q3: keep
        (0.1, 60, 0.1),  # never below one step
    ],
)
def test_the_range_state_machine(radius, n, expected):
    assert next_radius(radius, n, SPEC) == pytest.approx(expected)


def test_a_range_configuration_that_cannot_settle_is_refused():
    for bad, message in (
        ({"r0_m": 50.0}, "r0_m 50 is above r_max_m 35"),
        ({"n_min": 60}, "n_min 60 must be below n_max 50"),
        ({"dr_m": 0.0}, "dr_m"),
    ):
        with pytest.raises(Exception, match=message):
            build_config({"vehicle": {"ar": bad}})


def _world(seed: int, duration_s: float, radius_m: float = 8.0, speed_mps: float = 2.0):
    """A vehicle on a circle over point landmarks (a jittered 3 m grid), sighted within 3 m at 5 Hz
    with 5 cm and 0.01 rad of noise, odometry at 50 Hz with the datasheet's noise, the launch prior
    drawn from its own covariance: the messages in stamp order and the true poses every second."""
    rng = np.random.default_rng(seed)
    spec = build_config({}).sensors
    grid = np.arange(-radius_m - 6.0, radius_m + 6.0, 3.0)
    landmarks = np.array([(x, y) for x in grid for y in grid]) + rng.uniform(-1.0, 1.0, (len(grid) ** 2, 2))
    yaw_rate = speed_mps / radius_m
    messages, truth = [], {}
    prior_cov = np.diag([0.01, 0.01, 1e-4])
    prior = np.array([radius_m, 0.0, np.pi / 2]) + rng.multivariate_normal(np.zeros(3), prior_cov)
    messages.append(m.PosePrior(1, 0, 0, prior, prior_cov))
    R = np.diag([0.05**2, 0.01**2])
    seq = 0
    for k in range(round(duration_s * 1e6) // PERIOD_US + 1):
        t_us = k * PERIOD_US
        angle = yaw_rate * t_us * 1e-6
        pose = np.array([radius_m * np.cos(angle), radius_m * np.sin(angle), angle + np.pi / 2])
        if t_us % 1_000_000 == 0:
            truth[t_us] = pose
        if k:
            speed = speed_mps + rng.normal(0.0, spec.odom_speed_sigma_mps)
            rate = yaw_rate + rng.normal(0.0, spec.odom_yaw_rate_sigma_radps)
            messages.append(m.WheelOdometry(1, t_us, k, float(speed), float(rate)))
        if k % 10 == 0:
            d = landmarks - pose[:2]
            for ident in np.flatnonzero(np.hypot(d[:, 0], d[:, 1]) <= 3.0):
                r = np.hypot(*d[ident]) + rng.normal(0.0, 0.05)
                b = np.arctan2(d[ident, 1], d[ident, 0]) - pose[2] + rng.normal(0.0, 0.01)
                seq += 1
                messages.append(m.LandmarkSighting(1, t_us, seq, int(ident), float(r), float(b), R))
    return messages, truth


def _run(f, messages, truth):
    """Feed a filter in stamp order, cycling at 50 Hz: (pose NEES (k,), position errors (k,), state sizes (k,))."""
    nees, errors, sizes, t_us = [], [], [], 0
    for msg in messages:
        while t_us < msg.stamp_us:
            f.cycle(t_us)
            if t_us in truth:
                e = statistics.pose_error(f.x[:3], truth[t_us])
                nees.append(statistics.nees(e, f.P[:3, :3]))
                errors.append(np.hypot(e[0], e[1]))
                sizes.append(len(f.x))
            t_us += PERIOD_US
        f.handle(msg)
    return np.array(nees), np.array(errors), np.array(sizes)


def _filters(reentries=("reinit",)):
    spec = build_config({"sensors": {"odom_scale_prior_sigma": 0.0}}).sensors
    common = {"vehicle_id": 1, "spec": spec, "gate_probability": 0.9995}
    out = {"ekf-slam": ekf_slam.build(**common)}
    for rule in reentries:
        out[rule] = ar_ekf_slam.build(**common, ar=ArSlamConfig(**SMALL, reentry=rule))
    return out


def test_the_state_stays_bounded_while_ekf_slam_grows():
    messages, truth = _world(1, 150.0, radius_m=30.0, speed_mps=1.5)
    filters = _filters()
    full = _run(filters["ekf-slam"], messages, truth)[2]
    local = _run(filters["reinit"], messages, truth)[2]
    assert full[-1] > 2.5 * local.max()  # the full map keeps growing with the ground covered
    assert local[len(local) // 2 :].max() <= local[: len(local) // 2].max() + 20  # bounded
    assert len(filters["reinit"].state.landmarks.policy.xy) > 50  # the rest is retired


@pytest.mark.monte_carlo
def test_ar_ekf_slam_is_as_accurate_as_full_ekf_slam_and_consistent_where_naive_reentry_is_not():
    runs, checkpoints = 50, [28, 30, 32]  # seconds: after the loop closes (25 s) landmarks come back
    nees = {name: [] for name in ("ekf-slam", "reinit", "naive")}
    squared = {name: [] for name in nees}
    for seed in range(runs):
        messages, truth = _world(100 + seed, 33.0)
        for name, f in _filters(("reinit", "naive")).items():
            n, e, _ = _run(f, messages, truth)
            nees[name].append(n[list(checkpoints)])
            squared[name].append(np.mean(e**2))
    rmse = {name: float(np.sqrt(np.mean(v))) for name, v in squared.items()}
    low, high = statistics.chi2_band(3, runs=runs)
    anees = {name: np.mean(v, axis=0) for name, v in nees.items()}  # per checkpoint, over the runs
    kept = "reinit"
    assert rmse[kept] <= 1.3 * rmse["ekf-slam"], rmse
    assert np.all((anees[kept] >= low) & (anees[kept] <= high)), (anees[kept], low, high)
    assert np.all(anees["naive"] > high), anees["naive"]  # the control: old marginals double counted


def test_an_emptied_local_map_takes_its_range_out_to_the_frames_points_at_once_up_to_r_max():
    spec = ArSlamConfig()  # R0 25 m, n_min 8, R_max 35 m
    ahead = np.arange(26.0, 36.0)  # a frame's points 26-35 m away, all beyond R0
    assert ar_ekf_slam.regrown_radius(25.0, 0, ahead, spec) == 33.0  # the 8th nearest: dR would take 80 frames
    assert ar_ekf_slam.regrown_radius(25.0, 0, ahead + 10.0, spec) == spec.r_max_m  # no farther than R_max
    assert ar_ekf_slam.regrown_radius(25.0, 0, ahead[:7], spec) == 25.0  # fewer points than n_min
    assert ar_ekf_slam.regrown_radius(25.0, spec.n_min, ahead, spec) == 25.0  # a map that holds enough
    assert ar_ekf_slam.regrown_radius(30.0, 0, ahead - 10.0, spec) == 30.0  # never shrinks
