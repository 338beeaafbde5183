"""The ground station's fault plan: validated changes, one clear error that changes nothing, every
change and every start and end logged as an event; MAVLink link quality; the kill schedule."""

import pytest

from bus.faults import JamGnss, Kill, Loss
from bus.kill_schedule import KillSchedule
from bus.plan import FaultRequest
from groundstation.fault_control import FaultControl
from groundstation.link_quality import StreamQuality


def _control(*faults):
    log = []
    control = FaultControl(faults, vehicles=3, log=lambda kind, stamp, **fields: log.append((kind, stamp, fields)))
    return control, log


def test_faults_added_at_run_time_start_now_and_are_logged():
    control, log = _control(JamGnss(name="j", center_m=(0, 0), radius_m=5, start_s=1, for_s=2))
    control.advance(0)
    control.advance(5_000_000)
    reply = control.request(FaultRequest(op="add", fault=Loss(dst="v3", percent=30, for_s=10)))
    assert reply.ok and reply.plan.version == 1
    added = reply.plan.faults[-1]
    assert added.name == "loss-1" and added.start_s == 5.0
    control.advance(16_000_000)
    kinds = [(kind, stamp) for kind, stamp, _ in log]
    assert kinds == [
        ("fault_added", 0),
        ("fault_started", 1_000_000),
        ("fault_expired", 3_000_000),
        ("fault_added", 5_000_000),
        ("fault_started", 5_000_000),
        ("fault_expired", 15_000_000),
    ]
    assert [s.state for s in reply.states] == ["expired", "active"]


@pytest.mark.parametrize(
    "request_, message",
    [
        (FaultRequest(op="add", fault=Loss(dst="v7", percent=30)), "matches nothing"),
        (FaultRequest(op="add", fault=Kill(vehicle=9)), "vehicle 9 does not exist"),
        (FaultRequest(op="add", fault=Loss(name="j", percent=1)), "exists already"),
        (FaultRequest(op="remove", name="ghost"), "no fault named 'ghost'"),
        (FaultRequest(op="add"), "needs a fault"),
    ],
)
def test_bad_requests_get_one_clear_error_and_change_nothing(request_, message):
    control, log = _control(JamGnss(name="j", center_m=(0, 0), radius_m=5))
    before = control.plan()
    reply = control.request(request_)
    assert not reply.ok and message in reply.error
    assert control.plan() == before and log == []


def test_remove_and_clear_are_logged_and_bump_the_version():
    control, log = _control(JamGnss(name="a", center_m=(0, 0), radius_m=5), Loss(name="b", percent=5))
    assert control.request(FaultRequest(op="remove", name="a")).plan.version == 1
    reply = control.request(FaultRequest(op="clear"))
    assert reply.ok and reply.plan.faults == () and reply.plan.version == 2
    assert [(kind, fields["name"]) for kind, _, fields in log] == [("fault_removed", "a"), ("fault_removed", "b")]


def test_kill_schedule_kills_once_and_restarts_after_the_delay():
    schedule = KillSchedule()
    schedule.set_plan((Kill(name="k", vehicle=2, start_s=10, restart_after_s=5), Loss(percent=1)))
    assert schedule.due(9_000_000) == []
    assert schedule.due(10_000_000) == [("kill", 2, "k")]
    assert schedule.due(12_000_000) == []
    assert schedule.due(15_000_000) == [("restart", 2, "k")]
    assert schedule.due(30_000_000) == []


def test_link_quality_counts_losses_duplicates_and_late_frames_across_the_wrap():
    quality = StreamQuality()
    for seq in [250, 251, 253, 253, 254, 252, 255, 0, 3]:
        quality.see(seq)
    assert (quality.received, quality.duplicates, quality.reordered) == (9, 1, 1)
    assert quality.lost == 2  # 252 came late (not lost); 1 and 2 never came


def test_the_plan_is_bounded():
    from groundstation.fault_control import MAX_FAULTS

    control, _ = _control()
    for _ in range(MAX_FAULTS):
        assert control.request(FaultRequest(op="add", fault=Loss(dst="v3", percent=1))).ok
    reply = control.request(FaultRequest(op="add", fault=Loss(dst="v3", percent=1)))
    assert not reply.ok and "remove some first" in reply.error and len(reply.plan.faults) == MAX_FAULTS
