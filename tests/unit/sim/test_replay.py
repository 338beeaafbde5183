"""The replay world (sim.replay) and the calibration (sim.mrclam_calibration): what the robots
recorded reaches their vehicles as feed rows, on sim time, with truth; the calibration recovers the
noise, lag and sigmas a synthetic data set was made with."""

import numpy as np
import pytest

from bus import feed
from bus.config import build_config
from sim.mrclam_calibration import calibrate, sighting_sigmas
from sim.replay import ReplayWorld, odometry_rows, sighting_rows
from tests.synthetic_mrclam import synthetic


def _config(**replay) -> object:
    replay.setdefault("robots", [1, 2])
    return build_config(
        {
            "world": {"vehicles": len(replay["robots"])},
            "clock": {"duration_s": 40.0, "tick_s": 0.02},
            "replay": {"dataset": "synthetic", "start_s": 100.0, "calibration_s": [0, 100], **replay},
        }
    )


def test_odometry_in_force_at_the_start_is_stamped_zero_and_repeated_stamps_keep_the_first():
    odometry = np.array([[9.0, 0.1, 0.0], [10.5, 0.2, 0.1], [10.5000001, 0.3, 0.1], [11.0, 0.4, 0.2], [13.0, 0.5, 0.0]])
    stamps, rows = odometry_rows(odometry, start_s=10.0, end_s=12.0)
    assert stamps.tolist() == [0, 500_000, 1_000_000]
    assert rows[:, 0].tolist() == [0.1, 0.2, 0.4]


def test_sightings_split_into_landmarks_and_replayed_robots():
    sightings = np.array([[10.1, 7, 3.0, 0.1], [10.2, 2, 4.0, -0.2], [10.3, 5, 2.0, 0.3], [10.3, 9, 1.0, 0.0]])
    cov = np.diag([0.01, 0.0004])
    (ls, landmark), (ps, peers), skipped = sighting_rows(sightings, 10.0, 11.0, {1: 1, 2: 2}, (0.1, 0.02), False)
    assert ls.tolist() == [100_000, 300_000] and landmark[:, 0].tolist() == [7, 9]
    assert ps.tolist() == [200_000] and peers[0, :3].tolist() == [2, 4.0, -0.2]  # robot 2 is vehicle 2
    assert skipped == 1  # robot 5 is not replayed
    assert np.allclose(peers[0, 3:], cov.ravel()) and np.allclose(landmark[:, 3:], cov.ravel())
    # calibrated cameras: the range sigma is per metre of the range read
    (_, landmark), (_, peers), _ = sighting_rows(sightings, 10.0, 11.0, {1: 1, 2: 2}, (0.04, 0.02), True)
    assert np.allclose(landmark[:, 3], (0.04 * np.array([3.0, 1.0])) ** 2) and np.allclose(
        peers[:, 3], (0.04 * 4.0) ** 2
    )
    assert np.allclose(landmark[:, 6], 0.02**2)


def test_the_world_replays_every_row_once_in_ticks_that_decode():
    data = synthetic(np.random.default_rng(1), duration_s=140.0)
    world = ReplayWorld(_config(odom_lag_s=0.2, sighting_sigmas=[[0.1, 0.02], [0.2, 0.03]]), data)
    counts, truth_rows = {}, 0
    for tick in range(1, 2001):
        out = world.advance(tick * 20_000)
        truth_rows += len(out.truth_stamps)
        for vid in (1, 2):
            batch = feed.decode_batch(feed.encode_batch(feed.SensorBatch(vid, tick, tick * 20_000, out.blocks(vid))))
            for topic, (_, seq0, rows) in batch.blocks.items():
                assert seq0 == counts.get((vid, topic), 0), (vid, topic)  # consecutive across ticks
                counts[vid, topic] = seq0 + len(rows)
                if topic == "landmark":
                    expected = [0.1, 0.02] if vid == 1 else [0.2, 0.03]
                    assert np.allclose(rows[:, 3], (expected[0] * rows[:, 1]) ** 2)  # per metre of range
                    assert np.allclose(rows[:, 6], expected[1] ** 2)
    log = data.robots[2]
    lagged = log.odometry[:, 0] + 0.2
    assert counts[2, "odom"] == 1 + np.sum((lagged > 100.0) & (lagged <= 140.0))
    assert counts[2, "landmark"] == np.sum((log.sightings[:, 0] > 100.0) & (log.sightings[:, 0] <= 140.0))
    assert counts[1, "prior"] == 1 and truth_rows == 40 * 50 + 1


def test_withheld_landmarks_and_blackouts_send_nothing():
    data = synthetic(np.random.default_rng(2), duration_s=140.0)
    config = _config(withhold_landmarks=[2]).model_copy(
        update={
            "faults": build_config(
                {
                    "world": {"vehicles": 2},
                    "faults": [{"kind": "blackout", "vehicle": 1, "sensor": "odom", "start_s": 10.0, "for_s": 5.0}],
                }
            ).faults
        }
    )
    world = ReplayWorld(config, data)
    out = world.advance(40_000_000)
    assert "landmark" not in out.blocks(2) and len(out.blocks(1)["landmark"][0]) > 20
    odom = out.blocks(1)["odom"][0]
    assert not np.any((odom >= 10_000_000) & (odom <= 15_000_000)) and np.any(odom > 15_000_000)


def _rows_over(world: ReplayWorld, vid: int, topic: str, seconds: float) -> tuple[np.ndarray, np.ndarray]:
    """Stamps (k,) and rows (k, 7) of one vehicle's ``topic`` over ``seconds`` of 20 ms ticks."""
    stamps, rows = [np.zeros(0, np.int64)], [np.zeros((0, 7))]
    for tick in range(1, round(seconds * 50) + 1):
        block = world.advance(tick * 20_000).blocks(vid).get(topic)
        if block is not None:
            stamps.append(block[0])
            rows.append(block[2])
    return np.concatenate(stamps), np.concatenate(rows)


def test_each_robot_sighting_is_relayed_to_the_robot_seen_unless_it_was_lost():
    """Vehicle 1's ``seen`` rows are vehicle 2's sightings of it, row for row (observer 2 first),
    and a ranging blackout of the observer silences the relay with the sighting; no relay when it is off."""
    data = synthetic(np.random.default_rng(5), duration_s=140.0, robot_sighting_rate_hz=10.0)
    seen_stamps, seen = _rows_over(ReplayWorld(_config(), data), 1, "seen", 40.0)
    sighted_stamps, sighted = _rows_over(ReplayWorld(_config(), data), 2, "ranging", 40.0)
    assert len(seen) > 20 and np.array_equal(seen_stamps, sighted_stamps)
    assert np.all(seen[:, 0] == 2) and np.all(sighted[:, 0] == 1) and np.array_equal(seen[:, 1:], sighted[:, 1:])
    start_us = int(seen_stamps[0])  # a blackout over the first 2 s of sightings
    blackout = {"kind": "blackout", "vehicle": 2, "sensor": "ranging", "start_s": start_us * 1e-6, "for_s": 2.0}
    config = _config().model_copy(
        update={"faults": build_config({"world": {"vehicles": 2}, "faults": [blackout]}).faults}
    )
    stamps, _ = _rows_over(ReplayWorld(config, data), 1, "seen", 40.0)
    inside = (seen_stamps >= start_us) & (seen_stamps <= start_us + 2_000_000)
    assert inside.sum() >= 3 and np.array_equal(stamps, seen_stamps[~inside])
    unrelayed, _ = _rows_over(ReplayWorld(_config(relay_sightings=False), data), 1, "seen", 40.0)
    assert len(unrelayed) == 0


def test_truth_is_nan_where_vicon_lost_the_robot():
    data = synthetic(np.random.default_rng(3), duration_s=141.0)
    gt = data.robots[1].groundtruth
    cut = (gt[:, 0] > 110.0) & (gt[:, 0] < 112.0)  # a 2 s gap in Vicon
    data.robots[1] = data.robots[1].__class__(1, gt[~cut], data.robots[1].odometry, data.robots[1].sightings, 0)
    world = ReplayWorld(_config(), data)
    out = world.advance(40_000_000)
    gap = (out.truth_stamps > 10_000_000) & (out.truth_stamps < 12_000_000)  # between the samples around the cut
    assert np.all(np.isnan(out.truth[gap, 0])) and np.all(np.isfinite(out.truth[~gap, 0]))
    assert np.all(np.isfinite(out.truth[:, 1]))  # robot 2 was seen all along
    inside = np.flatnonzero(gap)[:40]  # a tick's worth of truth with the gap in it crosses the bus
    batch = feed.TruthBatch(
        1, int(out.truth_stamps[inside[-1]]), out.truth_stamps[inside], np.array([1, 2]), out.truth[inside]
    )
    decoded = feed.decode_truth(feed.encode_truth(batch))
    assert np.all(np.isnan(decoded.rows[:, 0])) and np.all(np.isfinite(decoded.rows[:, 1]))


def test_calibration_recovers_the_noise_a_data_set_was_made_with():
    data = synthetic(
        np.random.default_rng(4),
        robots=3,
        duration_s=300.0,
        lag_s=0.2,
        speed_sigma=0.05,
        rate_sigma=0.1,
        range_sigma=0.0,
        range_sigma_per_m=0.04,
        bearing_sigma=0.02,
    )
    cal = calibrate(data, (0.0, 300.0), (1, 2, 3))
    assert cal.odom_lag_s == pytest.approx(0.2, abs=0.021)
    # with a speed that hardly changes, time and distance travelled cannot be told apart: what counts is the
    # error variance the fitted model gives a 5 s window (1 m, 0.95 rad turned) against the one made
    along = cal.odom_speed_sigma_mps**2 * 0.015 * 5 + cal.odom_travel_sigma_m**2 * 1.0
    heading = cal.odom_yaw_rate_sigma_radps**2 * 0.015 * 5 + cal.odom_turn_sigma_rad**2 * 0.95
    assert along == pytest.approx(0.05**2 * 0.015 * 5, rel=0.3) and heading == pytest.approx(
        0.1**2 * 0.015 * 5, rel=0.3
    )
    assert cal.bearing_sigma_rad == pytest.approx(0.02, rel=0.15)
    per_robot = sighting_sigmas(data, (0.0, 300.0), (1, 2, 3))
    assert all(r == pytest.approx(0.04, rel=0.2) and b == pytest.approx(0.02, rel=0.2) for r, b in per_robot)
    assert cal.range_correlated_sigma_per_m < 0.01  # white noise: nothing persists


def test_calibration_finds_the_camera_latency_and_the_replay_stamps_sightings_when_taken():
    data = synthetic(np.random.default_rng(9), robots=3, duration_s=300.0, bearing_sigma=0.005, camera_latency_s=0.06)
    cal = calibrate(data, (0.0, 300.0), (1, 2, 3))
    assert cal.camera_latency_s == pytest.approx(0.06, abs=0.011)
    assert cal.bearing_sigma_rad == pytest.approx(0.005, rel=0.15)  # measured on the restamped sightings
    on_time = synthetic(np.random.default_rng(9), robots=3, duration_s=300.0, bearing_sigma=0.005)
    assert calibrate(on_time, (0.0, 300.0), (1, 2, 3)).camera_latency_s <= 0.01
    taken = data.robots[1].sightings[:, 0] - 0.06  # the replay stamps each sighting when it was taken
    taken = taken[(taken > 100.0) & (taken <= 140.0)]
    stamps_us = ReplayWorld(_config(camera_latency_s=0.06), data).advance(40_000_000).blocks(1)["landmark"][0]
    np.testing.assert_allclose(stamps_us, (taken - 100.0) * 1e6, atol=1.0)


def test_calibration_finds_range_error_that_persists():
    data = synthetic(
        np.random.default_rng(8),
        robots=3,
        duration_s=300.0,
        range_sigma=0.0,
        range_sigma_per_m=0.015,
        range_correlated_per_m=0.04,
        range_correlation_s=3.0,
        sighting_rate_hz=6.0,
    )
    cal = calibrate(data, (0.0, 300.0), (1, 2, 3))
    assert cal.range_correlated_sigma_per_m == pytest.approx(0.04, rel=0.25)
    # the correlation time is the coarser estimate (seeds 8-10 give 6.2, 2.0, 3.1 s for 3 s): within 2.5x
    assert 3.0 / 2.5 <= cal.range_correlation_s <= 3.0 * 2.5


def test_calibration_finds_bearing_error_that_persists():
    data = synthetic(
        np.random.default_rng(8),
        robots=3,
        duration_s=300.0,
        bearing_sigma=0.01,
        sighting_rate_hz=6.0,
        bearing_correlated_fraction=0.5,
        bearing_correlation_s=3.0,
    )
    cal = calibrate(data, (0.0, 300.0), (1, 2, 3))
    assert cal.bearing_correlated_fraction == pytest.approx(0.5, rel=0.25)
    assert 3.0 / 2.5 <= cal.bearing_correlation_s <= 3.0 * 2.5
    white = synthetic(np.random.default_rng(8), robots=3, duration_s=300.0, bearing_sigma=0.01, sighting_rate_hz=6.0)
    assert calibrate(white, (0.0, 300.0), (1, 2, 3)).bearing_correlated_fraction < 0.1


def test_calibration_finds_heading_error_that_grows_with_the_turns():
    data = synthetic(
        np.random.default_rng(6),
        robots=3,
        duration_s=400.0,
        lag_s=0.2,
        speed_sigma=0.02,
        rate_sigma=0.02,
        turn_sigma=0.1,
    )
    assert calibrate(data, (0.0, 400.0), (1, 2, 3)).odom_turn_sigma_rad == pytest.approx(0.1, rel=0.2)


def test_too_little_to_calibrate_on_says_so():
    data = synthetic(np.random.default_rng(5), duration_s=30.0)
    with pytest.raises(ValueError, match="too little to calibrate on"):
        calibrate(data, (0.0, 3.0), (1, 2))
