"""A restarted ground station: a half-written last line is cut before appending, and the tallies
and event counts already in the run directory are picked up."""

from groundstation.resume import resume_events, resume_tallies
from groundstation.rundir import METRICS_HEADER, RunDirectory

BOUNDS = (0.2, 9.3)


def test_partial_lines_are_cut_and_the_tallies_picked_up(tmp_path):
    (tmp_path / "metrics.csv").write_text(
        METRICS_HEADER
        + "0.020000,1,0.3,0.4,0.5,0.0,0.5,0.5,0.1,1.0,0,0.0\n"
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
