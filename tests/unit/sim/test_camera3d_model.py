"""The world's 3-D camera (sim.sensor_models.camera3d): a frame is the ground's points in view, each at
its true pixel under the paper's K up to the pixel noise (but for the tracker's rare slips), the same
for the same seed; the displacement comes once an earlier frame ``baseline_s`` back exists, and is
the camera's true displacement up to its scale error and noise."""

from __future__ import annotations

import numpy as np

from bus.config import build_config
from bus.sensors.camera3d import PAPER_K, look
from sim.sensor_models.camera3d import Camera3dModel, camera_position


def _flight(seed: int, frames: int = 12) -> list[np.ndarray]:
    config = build_config({"world": {"seed": seed}, "sensors": {"camera3d": {"rate_hz": 10}}})
    model, rng = Camera3dModel(config), np.random.default_rng(seed)
    poses = [np.array([-60.0 + 0.4 * k, -40.0, 0.2]) for k in range(frames)]
    return [model.measure(1, 100_000 * k, pose, config.sensors.camera3d, rng) for k, pose in enumerate(poses)]


def test_the_same_seed_gives_the_same_frames_and_another_seed_others():
    first, again, other = _flight(3), _flight(3), _flight(4)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert not np.array_equal(first[5], other[5])


def test_a_frame_s_pixels_are_its_points_projected_up_to_the_noise():
    config = build_config({"world": {"seed": 1}, "sensors": {"camera3d": {"rate_hz": 10}}})
    spec = config.sensors.camera3d
    model, rng = Camera3dModel(config), np.random.default_rng(0)
    misses = []
    for k in range(20):
        pose = np.array([-60.0 + 5.0 * k, -40.0, 0.2 + 0.3 * k])
        rows = model.measure(1, 2_000_000 * k, pose, spec, rng)
        C, R = camera_position(pose, spec), look(pose[2], np.deg2rad(spec.pitch_deg))
        camera = (model.points[rows[:, 0].astype(int)] - C) @ R  # R^T (X - C), row by row
        assert (np.linalg.norm(camera, axis=1) <= spec.see_m + 1e-9).all() and (camera[:, 2] > 0).all()
        true_uv = camera[:, :2] / camera[:, 2:] * np.diag(PAPER_K)[:2] + PAPER_K[:2, 2]
        misses.extend(np.linalg.norm(rows[:, 1:3] - true_uv, axis=1) / spec.pixel_sigma_px)
    assert len(misses) > 200
    assert np.mean(np.array(misses) < 4.0) > 0.96  # a slip in a hundred points is the world's, not the datasheet's


def test_the_displacement_comes_with_the_frame_a_baseline_later():
    frames = _flight(5)
    assert (frames[0][:, 4:8] == 0).all() and (frames[9][:, 7] == 0).all()  # nothing 1 s back yet
    spec = build_config({}).sensors.camera3d
    moved = frames[10][0, 4:7]
    truth = camera_position(np.array([-56.0, -40.0, 0.2]), spec) - camera_position(np.array([-60.0, -40.0, 0.2]), spec)
    assert frames[10][0, 7] == spec.baseline_s
    assert np.linalg.norm(moved - truth) < 5 * spec.baseline_sigma_m + 5 * spec.baseline_scale_sigma * np.linalg.norm(
        truth
    )
    assert (frames[10][:, 4:8] == frames[10][0, 4:8]).all()  # one displacement per frame


def test_the_world_s_truth_carries_each_uav_s_height_above_where_it_launched():
    """The truth's height column is how far the camera the world flies has climbed since the first
    truth (0 there), for every vehicle; a world without the 3-D camera flies level (0 throughout)."""
    from sim.world import World

    config = build_config({"world": {"vehicles": 3, "seed": 2}, "sensors": {"camera3d": {"rate_hz": 10}}})
    out = World(config).advance(20_000_000)
    rows = np.array(out.truth)  # (k, vehicles, 6)
    spec = config.sensors.camera3d
    climbed = [
        [camera_position(r[v, :3], spec)[2] - camera_position(rows[0, v, :3], spec)[2] for v in range(3)] for r in rows
    ]
    np.testing.assert_allclose(rows[:, :, 5], climbed, atol=1e-9)
    assert np.all(rows[0, :, 5] == 0.0) and np.ptp(rows[:, :, 5]) > 1.0  # it does climb and descend
    level = np.array(World(build_config({"world": {"vehicles": 2}})).advance(2_000_000).truth)
    assert np.all(level[:, :, 5] == 0.0)
