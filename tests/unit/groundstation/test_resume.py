"""A restarted ground station: a half-written last line is cut before appending, and the tallies
and event counts already in the run directory are picked up."""

import numpy as np

from bus.mavlink_codec import StateEstimate
from bus.odometry_content import NOT_ESTIMATED_VAR
from groundstation.resume import resume_events, resume_tallies
from groundstation.rundir import METRICS_HEADER, RunDirectory
from groundstation.scoring import Tally, score_all

BOUNDS = (0.2, 9.3)


def test_partial_lines_are_cut_and_the_tallies_picked_up(tmp_path):
    (tmp_path / "metrics.csv").write_text(
        METRICS_HEADER
        + "0.020000,1,0.3,0.4,0.5,0.0,0.5,0.5,0.1,1.0,0,0.0,,,\n"
        + "0.020000,2,1.0,0.0,1.0,0.0,0.5,0.5,0.1,20.0,0,0.0\n"
        + "0.040000,1,0.6,0.8,1.0,0.0,0.5,0.5,0.1,3.0,0,0.0\n"
        + "0.060000,1,0.6,0.8,1.0,0.0,0.5,0"
    )  # killed mid-line
    (tmp_path / "events.jsonl").write_text(
        '{"event": "run_started", "t_s": 0}\n{"event": "vehicle_lost", "t_s": 1}\n'
        '{"event": "fault_added", "t_s": 1}\n{"event": "fault_st'
    )
    tallies, last = resume_tallies(tmp_path / "metrics.csv", BOUNDS)
    assert tallies[1].samples == 2 and abs(tallies[1].sum_sq_position_m2 - 1.25) < 1e-9
    assert tallies[2].nees_inside == 0 and last == {1: 40_000, 2: 20_000}
    assert resume_events(tmp_path / "events.jsonl") == {"run_started": 1, "fault_added": 1}
    RunDirectory(tmp_path).close()
    lines = (tmp_path / "metrics.csv").read_text().splitlines()
    assert len(lines) == 4 and lines[-1].startswith("0.040000")
    assert (tmp_path / "events.jsonl").read_text().endswith('"fault_added", "t_s": 1}\n')


def test_a_restarted_ground_station_keeps_what_was_scored_height_and_consistency_included(tmp_path):
    """The tallies rebuilt from metrics.csv are those the scores made live (to the file's 6 decimals):
    the planar pose, its block consistency, and the height of a vehicle that estimates it; a level
    vehicle's rows leave the height columns empty and it gets no height tally."""
    rng = np.random.default_rng(5)
    ests, truths = [], []
    for k in range(300):
        vid = 1 + k % 2  # vehicle 2 flies level: its NED z is known to NOT_ESTIMATED_VAR
        cov = np.diag([0.04, 0.05, 0.3 if vid == 1 else NOT_ESTIMATED_VAR, 1e-4, 1e-4, 0.01])
        position = np.array([*rng.normal(size=2), rng.normal()])
        ests.append(StateEstimate(vid, 20_000 * (k // 2), position, 0.1, np.zeros(3), 0.0, cov, np.eye(6), 0))
        truths.append(np.array([*rng.normal(size=2) * 0.2, 0.1, rng.normal()]))
    scores = score_all(ests, truths)
    live: dict[int, Tally] = {}
    for s in scores:
        live.setdefault(s.vehicle_id, Tally()).add(s, BOUNDS)
    run = RunDirectory(tmp_path)
    run.write_scores(scores)
    run.close()
    assert all(line.endswith(",,") for line in (tmp_path / "metrics.csv").read_text().splitlines()[2::2])

    resumed, _ = resume_tallies(tmp_path / "metrics.csv", BOUNDS)
    for vid in (1, 2):
        a, b = live[vid], resumed[vid]
        assert (a.samples, a.nees_inside) == (b.samples, b.nees_inside)
        np.testing.assert_allclose([a.sum_sq_position_m2, a.sum_nees], [b.sum_sq_position_m2, b.sum_nees], rtol=1e-5)
        ca, cb = a.consistency.result(), b.consistency.result()
        assert (ca.samples, ca.blocks) == (cb.samples, cb.blocks) and ca.samples == 150
        np.testing.assert_allclose(ca.block_anees, cb.block_anees, rtol=1e-5)
    assert resumed[2].altitude is None and live[2].altitude is None
    ha, hb = live[1].altitude, resumed[1].altitude
    assert ha.samples == hb.samples == 150 and ha.consistency.dof == hb.consistency.dof == 1
    np.testing.assert_allclose(
        [ha.sum_sq_m2, ha.sum_nees, ha.max_error_m], [hb.sum_sq_m2, hb.sum_nees, hb.max_error_m], rtol=1e-5
    )
    np.testing.assert_allclose(ha.consistency.result().block_anees, hb.consistency.result().block_anees, rtol=1e-5)
