"""The fusion horizon: late measurements are fused as if they had come on time; too late ones and
duplicates are counted, never fused; checkpoints are taken only where a late one can land; the
divergence guard and the reset counter behave through replays."""

import dataclasses

import numpy as np
import pytest

from bus import messages as m
from bus.config import build_config
from experiments.harness import samples_of
from sim.world import World
from vehicle.estimators import ekf
from vehicle.estimators.filter import Filter
from vehicle.process.fusion import FusionHorizon

PERIOD_US = 20_000


def _feed(seconds: float, seed: int = 3) -> list[tuple[str, object]]:
    samples, _ = samples_of(World(build_config({"world": {"vehicles": 1, "seed": seed}})), round(seconds * 1e6))
    return [(topic, msg) for topic, msg in samples if topic != "ranging"]


def _ekf() -> Filter:
    return ekf.build(vehicle_id=1, spec=build_config({}).sensors, gate_probability=0.9995)


def _run(arrivals, horizon_us: int, end_us: int, every_cycles: int = 1, announce: bool = False):
    """Cycle every 20 ms; at cycle t, push the measurements whose arrival time is <= t first. With
    ``announce``, every late measurement is announced (expect) when its on-time slot comes."""
    est = _ekf()
    fusion = FusionHorizon(est, horizon_us=horizon_us, every_cycles=every_cycles)
    arrivals = sorted(arrivals, key=lambda a: a[0])
    late = sorted(msg.stamp_us for arrival, _, msg in arrivals if arrival > msg.stamp_us) if announce else []
    i = j = 0
    for t in range(0, end_us + 1, PERIOD_US):
        while j < len(late) and late[j] <= t:
            fusion.expect(late[j])
            j += 1
        while i < len(arrivals) and arrivals[i][0] <= t:
            fusion.push(arrivals[i][1], arrivals[i][2])
            i += 1
        fusion.cycle(t)
    return est, fusion


def _late_feed(feed):
    """Every GNSS fix and every 3rd odometry sample arrives 300 ms late."""
    return [
        (msg.stamp_us + (300_000 if topic == "gnss" or (topic == "odom" and msg.seq % 3 == 0) else 0), topic, msg)
        for topic, msg in feed
    ]


@pytest.mark.parametrize("every_cycles, announce", [(1, False), (0, True)], ids=["every cycle", "announced only"])
def test_late_measurements_inside_the_horizon_give_the_on_time_result(every_cycles, announce):
    feed = _feed(6.0)
    on_time, _ = _run([(msg.stamp_us, topic, msg) for topic, msg in feed], 500_000, 6_400_000)
    delayed, fusion = _run(_late_feed(feed), 500_000, 6_400_000, every_cycles, announce)
    assert fusion.counters.late_fused > 30 and fusion.counters.replays > 0
    assert fusion.counters.dropped_stale == 0
    np.testing.assert_allclose(delayed.x, on_time.x, atol=1e-9)
    np.testing.assert_allclose(delayed.P, on_time.P, atol=1e-12)


def test_checkpoints_are_taken_only_where_late_measurements_land():
    feed = _feed(6.0)
    _, every = _run(_late_feed(feed), 500_000, 6_400_000, every_cycles=1)
    _, announced = _run(_late_feed(feed), 500_000, 6_400_000, every_cycles=0, announce=True)
    assert every.counters.checkpoints >= 6_400_000 // PERIOD_US
    assert announced.counters.checkpoints < every.counters.checkpoints / 2
    # the V2V pattern: one fix per ranging epoch, fused 100 ms late: one checkpoint per late fix
    sparse = [(msg.stamp_us + (100_000 if topic == "gnss" else 0), topic, msg) for topic, msg in feed]
    _, fusion = _run(sparse, 500_000, 6_400_000, every_cycles=0, announce=True)
    late = sum(1 for topic, _ in feed if topic == "gnss")
    # the initial checkpoint (bound 0) serves the fix stamped 0
    assert fusion.counters.late_fused == late and fusion.counters.checkpoints == late
    _, on_time = _run([(msg.stamp_us, topic, msg) for topic, msg in feed], 500_000, 6_400_000, every_cycles=0)
    # nothing announced: the initial one and one a horizon (500 ms), so that the history kept is bounded
    assert on_time.counters.checkpoints == 1 + 6_400_000 // 500_000


def test_the_history_kept_for_replays_stays_bounded_when_nothing_is_announced():
    """A lockstep vehicle that fuses no neighbour announces nothing: it still keeps a checkpoint every
    horizon, so what it keeps for a replay is at most about two horizons' worth (a 10-minute run grew
    a vehicle by 50 MB while it kept everything since the start)."""
    feed = _feed(60.0)
    _, fusion = _run([(msg.stamp_us, topic, msg) for topic, msg in feed], 500_000, 60_000_000, every_cycles=0)
    per_s = len(feed) / 60.0
    assert len(fusion._applied) <= 2 * 0.5 * per_s + 1 and len(fusion._cycles) <= 2 * 0.5 * 50 + 1


def test_measurements_older_than_the_horizon_are_dropped_and_counted():
    feed = _feed(4.0)
    late = [(msg.stamp_us + (800_000 if topic == "gnss" else 0), topic, msg) for topic, msg in feed]
    _, fusion = _run(late, 500_000, 5_000_000)
    fixes = sum(1 for topic, _ in feed if topic == "gnss")
    assert fusion.counters.dropped_stale == fixes and fusion.counters.late_fused == 0


def test_duplicates_are_ignored_and_counted():
    feed = _feed(3.0)
    once, _ = _run([(msg.stamp_us, topic, msg) for topic, msg in feed], 500_000, 3_100_000)
    twice = [(msg.stamp_us, topic, msg) for topic, msg in feed]
    twice += [(msg.stamp_us + 40_000, topic, msg) for topic, msg in feed if topic in ("gnss", "odom")]
    doubled, fusion = _run(twice, 500_000, 3_100_000)
    assert fusion.counters.duplicates == sum(1 for topic, _ in feed if topic in ("gnss", "odom"))
    np.testing.assert_array_equal(doubled.x, once.x)


def test_the_duplicate_memory_stays_bounded_over_a_long_run():
    """A 10-minute soak grew every vehicle by 12% while this memory filled up: it is pruned to the
    horizon once it passes its bound, and duplicates inside the horizon are still caught."""
    from vehicle.process.fusion import MAX_SEEN

    feed = _feed(60.0)
    arrivals = [(msg.stamp_us, topic, msg) for topic, msg in feed]
    arrivals += [(msg.stamp_us + 40_000, topic, msg) for topic, msg in feed if topic == "gnss"]
    _, fusion = _run(arrivals, 500_000, 60_100_000)
    assert len(feed) > 2 * MAX_SEEN and len(fusion._seen) <= MAX_SEEN
    assert fusion.counters.duplicates == sum(1 for topic, _ in feed if topic == "gnss")


class _Poison:
    """A measurement that breaks the filter's covariance when applied (a numerical accident)."""

    def __init__(self, stamp_us: int, seq: int) -> None:
        self.stamp_us, self.seq = stamp_us, seq


class _Wrapped:
    """A filter seen through a test double: everything but ``handle`` is the filter's."""

    def __init__(self, inner: Filter) -> None:
        self.inner = inner

    def __getattr__(self, name: str):
        return getattr(self.inner, name)


class _Fragile(_Wrapped):
    def handle(self, msg):
        if isinstance(msg, _Poison):
            self.inner.P[0, 0] = np.nan
            return
        self.inner.handle(msg)


def test_divergence_guard_runs_in_replays_and_the_reset_counter_never_goes_down():
    feed = _feed(3.0)
    est = _Fragile(_ekf())
    fusion = FusionHorizon(est, horizon_us=500_000, every_cycles=1)
    seen_resets, i = [], 0
    for t in range(0, 3_000_001, PERIOD_US):
        while i < len(feed) and feed[i][1].stamp_us <= t:
            fusion.push(*feed[i])
            i += 1
        if t == 2_000_000:  # a poison stamped 1.9 s arrives late: the replay diverges and must recover
            fusion.push("poison", _Poison(1_900_000, 0))
        fusion.cycle(t)
        seen_resets.append(est.resets)
        assert np.all(np.isfinite(est.P)) and np.all(np.isfinite(est.x))
    assert fusion.counters.replays == 1 and est.resets == 1
    assert seen_resets == sorted(seen_resets)  # monotonic through the replay
    notices = est.notices.take()
    assert [n.text for n in notices].count("estimator reset: non-finite or indefinite covariance") == 1


def test_a_measurement_the_estimator_cannot_apply_is_counted_and_the_rest_is_fused():
    class Picky(_Wrapped):
        def handle(self, msg):
            if isinstance(msg, m.GnssFix) and msg.seq == 3:
                raise np.linalg.LinAlgError("singular innovation covariance")
            self.inner.handle(msg)

    est = Picky(_ekf())
    fusion = FusionHorizon(est, horizon_us=500_000, every_cycles=1)
    feed, i = _feed(2.0), 0
    for t in range(0, 2_000_001, PERIOD_US):
        while i < len(feed) and feed[i][1].stamp_us <= t:
            fusion.push(*feed[i])
            i += 1
        fusion.cycle(t)
    assert fusion.counters.failed == 1
    assert est.counters.gnss_accepted + est.counters.gnss_rejected == sum(1 for t, _ in feed if t == "gnss") - 1
    assert isinstance(feed[0][1], m.PosePrior) and est.initialized


class _CycleCounting(_Wrapped):
    """A filter that counts the cycles it runs (a replay runs some again)."""

    def __init__(self, inner: Filter) -> None:
        super().__init__(inner)
        self.cycles = 0

    def handle(self, msg):
        self.inner.handle(msg)

    def cycle(self, t_us: int) -> None:
        self.cycles += 1
        self.inner.cycle(t_us)


def _run_postponing(
    arrivals, end_us: int, scheduled, after_cycle: frozenset = frozenset()
) -> tuple[_CycleCounting, FusionHorizon]:
    """As a lockstep vehicle: every late measurement is announced when its on-time slot comes; a cycle
    at t is postponed while an announced measurement stamped <= t has not arrived, unless
    ``scheduled(t)`` (something is sent then), and runs before the next cycle that is not postponed."""
    est = _CycleCounting(_ekf())
    fusion = FusionHorizon(est, horizon_us=500_000, after_cycle=after_cycle)
    arrivals = sorted(arrivals, key=lambda a: a[0])
    late = sorted((msg.stamp_us, arrival) for arrival, _, msg in arrivals if arrival > msg.stamp_us)
    postponed, i = [], 0
    for t in range(0, end_us + 1, PERIOD_US):
        for stamp, _ in late:
            if stamp == t:
                fusion.expect(stamp)
        while i < len(arrivals) and arrivals[i][0] <= t:
            fusion.push(arrivals[i][1], arrivals[i][2])
            i += 1
        waiting = any(stamp <= t < arrival for stamp, arrival in late)
        if waiting and not scheduled(t) and t < end_us:
            postponed.append(t)
            fusion.postpone(t)
            continue
        for earlier in postponed + [t]:
            fusion.cycle(earlier)
        postponed = []
    return est, fusion


@pytest.mark.parametrize(
    "offset_us, schedule_us, after_cycle",
    [(0, 100_000, False), (40_000, 200_000, False), (0, 100_000, True)],
    ids=[
        "fix at a scheduled cycle",
        "fix arriving before the next scheduled cycle",
        "fix at a scheduled cycle, fused after it",
    ],
)
def test_postponed_cycles_give_the_replayed_result_with_fewer_cycles_run(offset_us, schedule_us, after_cycle):
    """The V2V pattern (a fix every 200 ms, fused 100 ms late): the cycles a late fix will revise wait
    for it instead of running twice. A fix stamped at a scheduled cycle (one that sends something)
    still replays that one cycle, unless its topic is fused after the cycle at its stamp; one that
    arrives before the next scheduled cycle replays nothing. The mean and covariance are the replay's
    to the bit either way."""
    feed = [
        (t, msg if t != "gnss" else dataclasses.replace(msg, stamp_us=msg.stamp_us + offset_us))
        for t, msg in _feed(4.0)
        if t != "gnss" or msg.stamp_us % 200_000 == 0
    ]
    arrivals = [(msg.stamp_us + (100_000 if topic == "gnss" else 0), topic, msg) for topic, msg in feed]
    replayed, before = _run_postponing(arrivals, 4_000_000, scheduled=lambda t: True)
    topics = frozenset({"gnss"}) if after_cycle else frozenset()
    postponed, after = _run_postponing(arrivals, 4_000_000, lambda t: t % schedule_us == 0, topics)
    fixes = sum(1 for arrival, topic, _ in arrivals if topic == "gnss" and arrival <= 4_000_000)
    assert fixes > 10 and before.counters.late_fused == after.counters.late_fused == fixes
    np.testing.assert_array_equal(postponed.x, replayed.x)
    np.testing.assert_array_equal(postponed.P, replayed.P)
    assert postponed.cycles < replayed.cycles
    if offset_us:
        _, on_time = _run_postponing([(msg.stamp_us, t, msg) for t, msg in feed], 4_000_000, lambda t: True)
        assert after.counters.replays == 0
        assert after.counters.checkpoints == on_time.counters.checkpoints  # none for the fixes
    elif after_cycle:
        assert after.counters.replays == 0 and postponed.cycles == 4_000_000 // PERIOD_US + 1  # none twice
    else:
        assert after.counters.replays == before.counters.replays == fixes
