"""The world: exact kinematics, seeded determinism, sensor rates, non-overlapping vehicles."""

import numpy as np

from bus import messages as m
from bus.config import build_config
from bus.keys import KeySpace
from sim.kinematics import unicycle_step
from sim.world import World


def test_exact_arc_matches_fine_euler_integration():
    pose = np.array([[0.0, 0.0, 0.3]])
    coarse = unicycle_step(pose, np.array([5.0]), np.array([0.4]), 0.5)
    fine = pose.copy()
    for _ in range(50_000):
        p = fine[0]
        fine = np.array([[p[0] + 5.0 * 1e-5 * np.cos(p[2]), p[1] + 5.0 * 1e-5 * np.sin(p[2]), p[2] + 0.4 * 1e-5]])
    np.testing.assert_allclose(coarse, fine, atol=1e-4)


def test_same_seed_same_bytes_other_seed_other_noise():
    cfg = build_config({"world": {"vehicles": 3, "seed": 7}})
    a, b = World(cfg).advance(2_000_000), World(cfg).advance(2_000_000)
    c = World(build_config({"world": {"vehicles": 3, "seed": 8}})).advance(2_000_000)
    assert a == b
    assert a != c


def test_sensor_rates_follow_the_config():
    world = World(build_config({"world": {"vehicles": 2}}))
    topics = [KeySpace().topic_of(key) for key, _ in world.advance(999_999)]  # exactly one second of stamps
    per_vehicle = {t: topics.count(t) / 2 for t in set(topics)}
    assert per_vehicle == {"imu": 100, "odom": 50, "gnss": 5, "truth": 50, "prior": 1, "ranging": 5}  # one peer each


def test_vehicles_never_come_close_to_each_other():
    world = World(build_config({"world": {"vehicles": 9, "seed": 3}}))
    keys, tracks = KeySpace(), {}
    for key, payload in world.advance(60_000_000):
        if key.endswith("/truth"):
            truth = m.decode(m.Truth, payload)
            tracks.setdefault(truth.stamp_us, []).append(truth.pose[:2])
    closest = min(np.min(np.linalg.norm(np.array(p)[:, None] - np.array(p)[None], axis=2) + np.eye(9) * 1e9)
                  for p in tracks.values())
    assert closest > 5.0


def _feed(messages, keys, vid, topic, cls):
    return [m.decode(cls, p) for k, p in messages if k == keys.sensor(vid, topic)]


def test_blackout_silences_one_feed_and_the_published_counts_say_so():
    faults = [{"kind": "blackout", "vehicle": 1, "sensor": "odom", "start_s": 1.0, "for_s": 1.0}]
    world, keys = World(build_config({"world": {"vehicles": 2, "seed": 3}, "faults": faults})), KeySpace()
    out = world.advance(3_000_000)
    odom1 = [o.stamp_us for o in _feed(out, keys, 1, "odom", m.WheelOdometry)]
    assert not [t for t in odom1 if 1_000_000 <= t < 2_000_000] and len(odom1) == 151 - 50
    assert len(_feed(out, keys, 2, "odom", m.WheelOdometry)) == 151
    counts = m.ClockTick(0, 3_000_000, 0, False, world.published())
    assert counts.published_by(1)["odom"] == 101 and counts.published_by(2)["odom"] == 151
    plain = World(build_config({"world": {"vehicles": 2, "seed": 3}})).advance(3_000_000)
    assert [p for k, p in out if k == keys.sensor(1, "imu")] == [p for k, p in plain if k == keys.sensor(1, "imu")]


def test_spoofed_fixes_drift_at_the_set_rate_and_jammed_ones_vanish():
    spoof = {"kind": "spoof-gnss", "center_m": [0, 0], "radius_m": 1e5, "drift_mps": 2.0, "heading_deg": 90, "start_s": 1.0}
    jam = {"kind": "jam-gnss", "center_m": [0, 0], "radius_m": 1e5, "start_s": 4.0}
    cfg = {"world": {"vehicles": 1, "seed": 3}}
    keys = KeySpace()
    plain = _feed(World(build_config(cfg)).advance(5_000_000), keys, 1, "gnss", m.GnssFix)
    faulty = _feed(World(build_config({**cfg, "faults": [spoof, jam]})).advance(5_000_000), keys, 1, "gnss", m.GnssFix)
    assert len(faulty) == 20 and faulty[-1].stamp_us == 3_800_000  # 5 Hz until the jammer at 4 s
    offsets = np.array([f.position_m - p.position_m for f, p in zip(faulty, plain)])
    stamps = np.array([f.stamp_us for f in faulty]) * 1e-6
    np.testing.assert_allclose(offsets[:, 0], 0.0, atol=1e-9)
    np.testing.assert_allclose(offsets[:, 1], np.where(stamps >= 1.0, 2.0 * (stamps - 1.0), 0.0), atol=1e-9)
