"""The world: exact kinematics, seeded determinism, sensor rates, non-overlapping vehicles."""

import numpy as np
import pytest

from bus import feed
from bus.config import build_config
from experiments.harness import samples_of
from sim import kinematics, noise_blocks
from sim.kinematics import unicycle_arcs
from sim.world import World


def test_exact_arc_matches_fine_euler_integration():
    pose = np.array([[0.0, 0.0, 0.3]])
    coarse = unicycle_arcs(pose, np.array([[5.0]]), np.array([[0.4]]), 0.5)
    fine = pose.copy()
    for _ in range(50_000):
        p = fine[0]
        fine = np.array([[p[0] + 5.0 * 1e-5 * np.cos(p[2]), p[1] + 5.0 * 1e-5 * np.sin(p[2]), p[2] + 0.4 * 1e-5]])
    np.testing.assert_allclose(coarse, fine, atol=1e-4)


def test_a_few_arcs_in_floats_equal_the_array_path(monkeypatch):
    """unicycle_arcs takes a few arcs one float at a time and many as arrays: the same arithmetic
    (straight arcs included), so the same poses to rounding."""
    rng = np.random.default_rng(3)
    pose = rng.normal(0.0, 10.0, (3, 3))
    speed, rate = rng.normal(2.0, 1.0, (5, 3)), rng.normal(0.0, 0.5, (5, 3))
    rate[2, 1] = 0.0
    floats = unicycle_arcs(pose, speed, rate, 0.002)
    monkeypatch.setattr(kinematics, "SCALAR_ARCS", 0)
    arrays = unicycle_arcs(pose, speed, rate, 0.002)
    np.testing.assert_allclose(floats, arrays, rtol=0, atol=1e-12)


def _encoded(world: World, until_us: int, step_us: int) -> tuple[list[bytes], list[np.ndarray]]:
    """Every vehicle's batches (encoded) and the truth, advancing in ticks of ``step_us``."""
    batches, truth = [], []
    for end in range(step_us, until_us + 1, step_us):
        out = world.advance(end)
        batches += [feed.encode_batch(feed.SensorBatch(v, 0, end, out.blocks(v))) for v in world.vehicle_ids()]
        truth += out.truth
    return batches, truth


def _all_samples(world: World, until_us: int, vid: int) -> list[tuple[str, object]]:
    return samples_of(world, until_us, vid)[0]


def test_same_seed_same_bytes_other_seed_other_noise():
    cfg = build_config({"world": {"vehicles": 3, "seed": 7}})
    a, b = _encoded(World(cfg), 2_000_000, 100_000), _encoded(World(cfg), 2_000_000, 100_000)
    c = _encoded(World(build_config({"world": {"vehicles": 3, "seed": 8}})), 2_000_000, 100_000)
    assert a[0] == b[0]
    assert a[0] != c[0]


def test_when_a_vehicle_draws_its_next_block_changes_nothing_the_world_measures(monkeypatch):
    cfg = build_config({"world": {"vehicles": 3, "seed": 7}})
    spread = _encoded(World(cfg), 2_500_000, 100_000)  # three blocks of noise; truth included
    monkeypatch.setattr(noise_blocks, "draw_ahead_step", lambda index, vehicles: noise_blocks.BLOCK_STEPS - 1 - index)
    late = _encoded(World(cfg), 2_500_000, 100_000)
    assert spread[0] == late[0]
    assert all(np.array_equal(a, b) for a, b in zip(spread[1], late[1], strict=True))


def test_the_tick_length_changes_nothing_the_world_measures():
    cfg = build_config({"world": {"vehicles": 3, "seed": 7}})
    per_tick = {
        step: [msg for v in (1, 2, 3) for msg in _samples_by_ticks(World(cfg), 3_000_000, step, v)]
        for step in (20_000, 100_000, 1_000_000)
    }
    reference = per_tick[20_000]
    for step, samples in per_tick.items():
        assert len(samples) == len(reference)
        for (t1, a), (t2, b) in zip(samples, reference):
            assert t1 == t2 and a.stamp_us == b.stamp_us and a.seq == b.seq
            for name in a.__dataclass_fields__:
                assert np.array_equal(np.asarray(getattr(a, name)), np.asarray(getattr(b, name))), (step, name)


def _samples_by_ticks(world: World, until_us: int, step_us: int, vid: int) -> list[tuple[str, object]]:
    out = []
    for end in range(step_us, until_us + 1, step_us):
        batch = feed.encode_batch(feed.SensorBatch(vid, 0, end, world.advance(end).blocks(vid)))
        out += feed.decode_batch(batch).samples()
    return out


def test_sensor_rates_follow_the_config():
    world = World(build_config({"world": {"vehicles": 2}}))
    topics = [topic for topic, _ in _all_samples(world, 999_999, 1)]  # exactly one second of stamps
    assert {t: topics.count(t) for t in set(topics)} == {"imu": 100, "odom": 50, "gnss": 5, "prior": 1, "ranging": 5}


def test_ranging_reaches_only_the_nearest_peers():
    world = World(build_config({"world": {"vehicles": 9, "seed": 2}, "sensors": {"ranging_max_peers": 3}}))
    start = world.poses[:, :2].copy()
    out = world.advance(999_999)
    for i, vid in enumerate(world.vehicle_ids()):
        rows = out.rows[vid]["ranging"]
        assert len(rows) == 5 * 3  # 5 epochs x 3 peers
        first_epoch = sorted(int(r[2][0]) for r in rows if r[0] == 0)
        nearest = np.argsort(np.linalg.norm(start - start[i], axis=1), kind="stable")[1:4] + 1
        assert first_epoch == sorted(nearest.tolist())


def test_listeners_are_exactly_the_vehicles_that_ranged_each_one():
    world = World(build_config({"world": {"vehicles": 9, "seed": 2}, "sensors": {"ranging_max_peers": 3}}))
    out = world.advance(999_999)
    pairs = {(observer, int(row[2][0])) for observer, topics in out.rows.items() for row in topics["ranging"]}
    listeners = out.listeners()
    assert {(observer, target) for target, observers in listeners.items() for observer in observers} == pairs
    assert all(
        list(observers) == sorted(observers) and target not in observers for target, observers in listeners.items()
    )
    quiet = World(build_config({"world": {"vehicles": 9, "seed": 2}}))
    quiet.advance(100_000)
    assert quiet.advance(150_000).listeners() == {}  # no ranging epoch in (100, 150] ms


def test_vehicles_never_come_close_to_each_other():
    world = World(build_config({"world": {"vehicles": 9, "seed": 3}}))
    out = world.advance(60_000_000)
    tracks = np.array(out.truth)[:, :, :2]  # (k, 9, 2)
    gaps = np.linalg.norm(tracks[:, :, None] - tracks[:, None, :], axis=3) + np.eye(9) * 1e9
    assert gaps.min() > 5.0


def test_blackout_silences_one_feed_and_nothing_else():
    faults = [{"kind": "blackout", "vehicle": 1, "sensor": "odom", "start_s": 1.0, "for_s": 1.0}]
    config = build_config({"world": {"vehicles": 2, "seed": 3}, "faults": faults})
    odom1 = [msg.stamp_us for t, msg in _all_samples(World(config), 3_000_000, 1) if t == "odom"]
    assert not [t for t in odom1 if 1_000_000 <= t < 2_000_000] and len(odom1) == 151 - 50
    assert len([1 for t, _ in _all_samples(World(config), 3_000_000, 2) if t == "odom"]) == 151
    plain = build_config({"world": {"vehicles": 2, "seed": 3}})
    imu = [msg.gyro_radps.tolist() for t, msg in _all_samples(World(config), 3_000_000, 1) if t == "imu"]
    assert imu == [msg.gyro_radps.tolist() for t, msg in _all_samples(World(plain), 3_000_000, 1) if t == "imu"]


def test_spoofed_fixes_drift_at_the_set_rate_and_jammed_ones_vanish():
    spoof = {
        "kind": "spoof-gnss",
        "center_m": [0, 0],
        "radius_m": 1e5,
        "drift_mps": 2.0,
        "heading_deg": 90,
        "start_s": 1.0,
    }
    jam = {"kind": "jam-gnss", "center_m": [0, 0], "radius_m": 1e5, "start_s": 4.0}
    cfg = {"world": {"vehicles": 1, "seed": 3}}

    def fixes(config):
        return [msg for t, msg in _all_samples(World(build_config(config)), 5_000_000, 1) if t == "gnss"]

    plain, faulty = fixes(cfg), fixes({**cfg, "faults": [spoof, jam]})
    assert len(faulty) == 20 and faulty[-1].stamp_us == 3_800_000  # 5 Hz until the jammer at 4 s
    offsets = np.array([f.position_m - p.position_m for f, p in zip(faulty, plain)])
    stamps = np.array([f.stamp_us for f in faulty]) * 1e-6
    np.testing.assert_allclose(offsets[:, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(offsets[:, 1], np.where(stamps >= 1.0, 2.0 * (stamps - 1.0), 0.0), atol=1e-9)


@pytest.mark.parametrize(("phase", "first_us"), [(None, 0), (0.5, 100_000), (0.25, 50_000), (0.99, 0)])
def test_gnss_fixes_come_at_their_phase_of_the_period(phase, first_us):
    """5 Hz fixes at (k + phase) / 5 s, to the nearest 10 ms IMU step (0.99 of 200 ms rounds to the
    next period's start); by default with the ranging epochs, off them at any other phase."""
    sensors = {} if phase is None else {"sensors": {"gnss_phase": phase}}
    world = World(build_config({"world": {"vehicles": 2, "seed": 1}, **sensors}))
    samples = _all_samples(world, 2_000_000, 1)
    gnss = [msg.stamp_us for t, msg in samples if t == "gnss"]
    ranging = {msg.stamp_us for t, msg in samples if t == "ranging"}
    assert gnss == list(range(first_us, 2_000_001, 200_000))
    assert ranging and ranging.isdisjoint(gnss) == (first_us % 200_000 != 0)


def _imu_by_tick(faults: list, seconds: int = 3) -> dict[int, list[tuple]]:
    """vehicle id -> per one-second advance, its IMU block (stamps, first seq, rows) or None."""
    world = World(build_config({"world": {"vehicles": 3, "seed": 4}, "faults": faults}))
    outputs = [world.advance(t * 1_000_000) for t in range(1, seconds + 1)]
    return {v: [out.blocks(v).get("imu") for out in outputs] for v in world.vehicle_ids()}


def test_a_silenced_imu_leaves_out_its_samples_only():
    """The IMU is measured for every vehicle at once: a blackout of vehicle 2's IMU from 1.305 to 1.605 s
    takes exactly those samples out of its feed, its sequence numbers go on without a gap (they count
    what was sent), and every other sample of every vehicle is the same as without the blackout."""
    blackout = {"kind": "blackout", "vehicle": 2, "sensor": "imu", "start_s": 1.305, "for_s": 0.3}
    quiet, silenced = _imu_by_tick([]), _imu_by_tick([blackout])
    for vid in (1, 3):
        for (s0, q0, r0), (s1, q1, r1) in zip(quiet[vid], silenced[vid]):
            assert q0 == q1 and np.array_equal(s0, s1) and np.array_equal(r0, r1)
    heard = 0
    for (stamps, _, rows), (kept, seq0, kept_rows) in zip(quiet[2], silenced[2]):
        mask = (stamps < 1_305_000) | (stamps > 1_605_000)
        assert np.array_equal(kept, stamps[mask]) and np.array_equal(kept_rows, rows[mask])
        assert seq0 == heard  # numbered as sent
        heard += len(kept)
    assert heard == 301 - 30


def test_a_batch_lists_its_topics_in_the_order_a_step_measures_them():
    """Feeds name their topics in the order the world measures them within a step (the prior first,
    at 0; then IMU, wheels, GNSS, ranging), whichever of them are measured one vehicle at a time."""
    world = World(build_config({"world": {"vehicles": 3, "seed": 4}}))
    assert list(world.advance(0).blocks(1)) == ["prior", "imu", "odom", "gnss", "ranging"]
    assert list(world.advance(1_000_000).blocks(1)) == ["imu", "odom", "gnss", "ranging"]
