"""The swarm benchmark's realtime rows: which cases are held to the targets, and against what."""

from bench.bench_swarm import MAX_JITTER_US, RETIRED, realtime_rows


def _run(jitter_us: float, stale: int = 0, target: str = "overruns < 1%") -> dict:
    return {
        "target": target,
        "overrun_rate": 0.0001,
        "jitter_p99_us": jitter_us,
        "dropped_stale": stale,
        "loop_priority": 10,
    }


def _met(rows) -> dict:
    return {row.metric.split(" (")[0]: row.met for row in rows}


def test_a_held_case_is_judged_by_its_median_run_and_its_worst_stale_count():
    runs = [_run(4900.0), _run(5100.0, stale=3), _run(1200.0)]
    rows = realtime_rows("realtime 50 Hz, 20 vehicles", _run(4900.0), runs)
    assert _met(rows) == {"loop overruns": True, "jitter p99": True, "samples dropped as stale": False}
    assert rows[1].metric == "jitter p99 (median run of 3)" and rows[2].value == 3


def test_a_jitter_at_the_allowance_fails_the_target():
    rows = realtime_rows("realtime 50 Hz, 20 vehicles", _run(MAX_JITTER_US + 70.0), [_run(MAX_JITTER_US + 70.0)])
    assert _met(rows)["jitter p99"] is False


def test_the_control_is_held_only_to_dropping_nothing():
    r = _run(16000.0, stale=2, target="-")
    assert _met(realtime_rows("fair", r, [r])) == {
        "loop overruns": None,
        "jitter p99": None,
        "samples dropped as stale": False,
    }


def test_a_retired_case_is_reported_and_held_to_nothing():
    r = _run(30000.0, stale=4000, target=RETIRED)
    rows = realtime_rows("realtime 50 Hz, 32 vehicles", r, [r])
    assert all(row.met is None for row in rows)
    assert all(RETIRED in row.target for row in rows)
    assert [row.value for row in rows] == [0.01, 30.0, 4000]
