"""The run directory's metrics rows and TUM lines say what each score says, in the documented formats
(written for a release of scores at once)."""

from __future__ import annotations

import numpy as np

from bus.mavlink_codec import StateEstimate
from groundstation.rundir import RunDirectory
from groundstation.scoring import score_all


def _scores(rng: np.random.Generator, n: int):
    ests, truths = [], []
    for k in range(n):
        a = rng.normal(size=(6, 6)) * rng.uniform(1e-3, 3)
        position = rng.normal(size=3) * 10.0 ** rng.integers(-3, 3)
        yaw = rng.uniform(-np.pi, np.pi)
        vid, stamp_us = 1 + k % 4, 20_000 * k + 7
        ests.append(StateEstimate(vid, stamp_us, position, yaw, np.zeros(3), 0.0, a @ a.T, np.eye(6), k % 3))
        truths.append(np.array([*rng.normal(size=2) * 10, rng.uniform(-np.pi, np.pi), rng.normal() * 5]))
    return score_all(ests, truths), truths


def test_each_score_is_a_metrics_row_and_an_estimate_and_truth_tum_line(tmp_path):
    scores, truths = _scores(np.random.default_rng(11), 40)
    true_height = {id(s): t[3] for s, t in zip(scores, truths, strict=True)}
    run = RunDirectory(tmp_path)
    run.write_scores(scores)
    run.flush()
    rows = (tmp_path / "metrics.csv").read_text().splitlines()[1:]
    assert len(rows) == len(scores)
    for s, row in zip(scores, rows, strict=True):
        f = row.split(",")
        assert float(f[0]) == round(s.stamp_us * 1e-6, 6) and int(f[1]) == s.vehicle_id
        np.testing.assert_allclose([float(x) for x in (f[2], f[3], f[5])], s.error_m, atol=5e-7)
        np.testing.assert_allclose(float(f[4]), np.hypot(*s.error_m[:2]), atol=5e-7)
        np.testing.assert_allclose([float(x) for x in f[6:9]], np.sqrt(np.diag(s.pose_covariance)), atol=5e-7)
        np.testing.assert_allclose(float(f[9]), s.nees, atol=5e-7)
        assert int(f[10]) == s.reset_counter
        np.testing.assert_allclose(float(f[11]), s.pose_covariance[0, 1], atol=5e-10)
        height = [s.altitude_error_m, np.sqrt(s.estimate.pose_covariance[2, 2]), s.altitude_nees]
        np.testing.assert_allclose([float(x) for x in f[12:15]], height, rtol=1e-6, atol=5e-7)
    for vid in {s.vehicle_id for s in scores}:
        mine = [s for s in scores if s.vehicle_id == vid]
        for kind in ("est", "truth"):
            lines = (tmp_path / "tum" / f"{kind}_v{vid}.tum").read_text().splitlines()
            assert len(lines) == len(mine)
            for s, line in zip(mine, lines, strict=True):
                x, y, yaw = (*s.estimate.position_m[:2], s.estimate.yaw_rad) if kind == "est" else s.truth_pose
                z = s.estimate.position_m[2]  # a level vehicle's truth flies at its estimate's altitude
                if kind == "truth" and s.estimate.pose_covariance[2, 2] > 1e-6:  # it estimates its height
                    z = -true_height[id(s)]  # NED
                # TUM: timestamp tx ty tz qx qy qz qw, the attitude a yaw about z
                attitude = f"0 0 {np.sin(yaw / 2):.9f} {np.cos(yaw / 2):.9f}"
                assert line == f"{s.stamp_us * 1e-6:.6f} {x:.6f} {y:.6f} {z:.6f} {attitude}"
