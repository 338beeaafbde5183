"""A 3-D flight as Lichtblick sees it (experiments.ar_slam3d_recording): each landmark's ellipsoid is
its covariance's 3-sigma ellipsoid (its axes and their lengths), every frame reaches the map, the
camera and the plots, and the JSON schema and the layout are ones Lichtblick accepts."""

import json

import numpy as np
from mcap.reader import make_reader

from experiments.ar_slam3d import fly, world
from experiments.ar_slam3d_recording import FLIGHT_SCHEMA, LAYOUT, MCAP, FlightRecording
from groundstation.scene_primitives import ellipsoid
from tests.viewer_rules import json_schema_errors, lichtblick_layout_errors


def _rotation(q: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def test_an_ellipsoid_is_its_covariances_three_sigma_ellipsoid():
    rng = np.random.default_rng(3)
    for _ in range(50):
        A = rng.normal(size=(3, 3))
        covariance = A @ A.T + 1e-3 * np.eye(3)
        size, q = ellipsoid(covariance)
        assert abs(np.linalg.norm(q) - 1.0) < 1e-12
        R = _rotation(q)
        rebuilt = R @ np.diag((size / 6.0) ** 2) @ R.T  # diameters of 3 sigma along the rotated axes
        np.testing.assert_allclose(rebuilt, covariance, rtol=1e-9, atol=1e-12)


def test_a_thin_ellipsoid_lies_along_its_long_axis():
    along = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    covariance = 4.0 * np.outer(along, along) + 0.01 * np.eye(3)
    size, q = ellipsoid(covariance)
    longest = _rotation(q)[:, int(np.argmax(size))]
    assert abs(abs(longest @ along) - 1.0) < 1e-9
    assert size.max() / size.min() > 15.0


def test_every_frame_is_recorded_with_a_layout_lichtblick_accepts(tmp_path):
    frames = 40
    recording = FlightRecording(tmp_path, world(2, frames + 1)[1])
    fly(2, frames, "adaptive", on_frame=recording.frame)
    recording.close()
    with (tmp_path / MCAP).open("rb") as f:
        counts: dict[str, int] = {}
        for _, channel, _ in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    assert counts["/map3d"] == counts["/camera3d"] == counts["/flight3d"] == frames
    assert counts["/relief3d"] == 1 and counts["/track3d"] == frames // 10
    assert json_schema_errors(FLIGHT_SCHEMA) == []
    assert lichtblick_layout_errors(json.loads((tmp_path / LAYOUT).read_text())) == []
