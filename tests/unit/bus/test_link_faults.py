"""Link faults in the receiving bus layer: each fault's measured effect matches what was asked,
decisions are reproducible from the seed, and selection follows the globs."""

import numpy as np
import pytest

from bus.faults import Delay, Duplicate, Loss, Reorder
from bus.link_faults import Arrival, LinkFaultStage

N = 20_000
STEP_US = 10_000


def _through(
    stage: LinkFaultStage, n: int = N, key: str = "swarm/v/3/sensor/imu", topic: str = "imu", src: str = "v3"
) -> list[tuple[int, int]]:
    """Offer n packets stamped every 10 ms; returns (seq, delivery time us) in delivery order."""
    out = []
    for seq in range(n):
        t = seq * STEP_US
        out += [(s, t) for s, _ in stage.release(t)]
        out += [(s, t) for s, _ in stage.offer(Arrival(key, src, topic, t, (seq, t)))]
    out += [(s, 10**15) for s, _ in stage.release(10**15)]
    return out


def test_random_loss_drops_the_asked_share():
    out = _through(LinkFaultStage("v3", seed=1, faults=(Loss(name="l", dst="v3", percent=30),)))
    assert 1 - len(out) / N == pytest.approx(0.30, abs=0.015)


def test_gilbert_elliott_loss_comes_in_bursts_of_the_asked_length():
    out = {s for s, _ in _through(LinkFaultStage("v3", seed=2, faults=(Loss(name="ge", percent=20, burst=5),)))}
    lost = np.array([s not in out for s in range(N)])
    runs = np.diff(np.flatnonzero(np.diff(np.r_[0, lost.astype(int), 0])))[::2]  # lengths of loss runs
    assert lost.mean() == pytest.approx(0.20, abs=0.03)
    assert runs.mean() == pytest.approx(5.0, rel=0.15)


def test_duplication_delivers_the_asked_share_twice():
    out = _through(LinkFaultStage("gs", seed=3, faults=(Duplicate(name="d", percent=10),)))
    assert len(out) / N - 1 == pytest.approx(0.10, abs=0.01)


@pytest.mark.parametrize("distribution", ["uniform", "normal", "pareto"])
def test_delay_has_the_asked_mean_and_spread(distribution):
    fault = Delay(name="d", delay_s=0.2, jitter_s=0.05, distribution=distribution)
    stage = LinkFaultStage("gs", seed=4, faults=(fault,))
    latency_s = []
    for seq in range(5000):
        t = seq * STEP_US
        assert stage.offer(Arrival("k", "v1", "mavlink", t, t)) == []  # nothing delay-free
        latency_s += [(t - sent) * 1e-6 for sent in stage.release(t)]
    latency = np.array(latency_s)
    assert latency.mean() == pytest.approx(0.2 + STEP_US * 0.5e-6, abs=0.01)  # + half a release step
    if distribution == "uniform":
        assert latency.min() >= 0.15 - 1e-9 and latency.max() <= 0.25 + STEP_US * 1e-6
    elif distribution == "normal":
        assert latency.std() == pytest.approx(0.05, rel=0.1)
    else:
        assert latency.min() >= 0.15 - 1e-9 and np.percentile(latency, 99.9) > 0.35  # heavy tail


def test_reorder_holds_back_the_asked_share_so_later_packets_overtake():
    out = _through(LinkFaultStage("v1", seed=5, faults=(Reorder(name="r", percent=25, gap_s=0.05),)))
    seqs = [s for s, _ in out]
    overtaken = np.array(seqs[1:]) < np.maximum.accumulate(seqs)[:-1]  # arrived after a later-sent packet
    assert sorted(seqs) == list(range(N))
    assert overtaken.mean() == pytest.approx(0.25, abs=0.015)


def _kept(stage: LinkFaultStage, order: list[tuple[str, int]]) -> dict[str, list[int]]:
    """Offer packets (key, number) in ``order``; which numbers come out, per key."""
    for key, i in order:
        stage.offer(Arrival(key, "v1", "imu", i, (key, i)))
    out: dict[str, list[int]] = {}
    for key, i in stage.release(10**12):
        out.setdefault(key, []).append(i)
    return {k: sorted(v) for k, v in out.items()}


def test_decisions_are_reproducible_and_independent_of_key_interleaving():
    faults = (Loss(name="l", percent=40),)
    interleaved = [(k, i) for i in range(500) for k in ("x", "y")]
    one_after_other = [(k, i) for k in ("y", "x") for i in range(500)]
    kept = _kept(LinkFaultStage("v1", seed=9, faults=faults), interleaved)
    assert kept == _kept(LinkFaultStage("v1", seed=9, faults=faults), one_after_other)
    assert 0.5 < len(kept["x"]) / 500 < 0.7
    assert kept != _kept(LinkFaultStage("v1", seed=10, faults=faults), interleaved)


def test_selected_packets_come_out_in_stamp_order_whatever_their_arrival():
    stage = LinkFaultStage("gs", seed=1, faults=(Duplicate(name="d", percent=0),))
    for stamp in (30, 10, 20):
        assert stage.offer(Arrival("k", "v1", "mavlink", stamp, stamp)) == []
    assert stage.release(20) == [10, 20] and stage.release(100) == [30]
    assert LinkFaultStage("gs", seed=1).offer(Arrival("k", "v1", "mavlink", 5, "now")) == ["now"]  # no fault: at once


def test_faults_select_by_source_destination_topic_and_time():
    fault = Loss(name="l", src="v[12]", dst="gs", topic="mav*", percent=100, start_s=1.0, for_s=1.0)
    stage = LinkFaultStage("gs", seed=0, faults=(fault,))

    def offer(src: str, topic: str, t_s: float) -> bool:
        now = stage.offer(Arrival(f"{src}/{topic}", src, topic, round(t_s * 1e6), 0))
        return bool(now + stage.release(10**12))

    assert not offer("v1", "mavlink", 1.5) and not offer("v2", "mavlink", 1.0)
    assert offer("v3", "mavlink", 1.5) and offer("v1", "imu", 1.5)
    assert offer("v1", "mavlink", 0.9) and offer("v1", "mavlink", 2.0)
    assert LinkFaultStage("v1", seed=0, faults=(fault,)).faults == ()  # not addressed to v1


def test_traffic_passed_untouched_before_a_fault_leaves_its_draws_as_if_offered():
    """The bus layer skips offering packet by packet while no fault targets the receiver; a fault set
    later must still decide each packet as it would have had every earlier one been offered."""
    loss = (Loss(name="l", percent=50),)
    offered, counted = LinkFaultStage("v1", seed=3), LinkFaultStage("v1", seed=3)
    for t in range(100):
        assert offered.offer(Arrival("k", "v2", "imu", t, t)) == [t]
    assert counted.untouched("k", 100) and not LinkFaultStage("v1", seed=3, faults=loss).untouched("k")
    offered.set_plan(loss), counted.set_plan(loss)
    after = [Arrival("k", "v2", "imu", t, t) for t in range(100, 400)]
    for stage in (offered, counted):
        assert all(stage.offer(a) == [] for a in after)  # selected: they come out of release()
    kept = offered.release(10**9)
    assert kept == counted.release(10**9) and 100 < len(kept) < 200
