"""The realtime loop's scheduling class (vehicle.process.scheduling): granted where the kernel allows it, the
fair scheduler with a log line where it does not, nothing asked at priority 0."""

from __future__ import annotations

import logging
import os

import pytest

from vehicle.process.scheduling import ask_for_realtime_priority


def test_priority_zero_asks_the_kernel_for_nothing(monkeypatch):
    calls = []
    monkeypatch.setattr(os, "sched_setscheduler", lambda *a: calls.append(a), raising=False)
    assert ask_for_realtime_priority(0) == 0
    assert calls == []


def test_a_granted_priority_puts_the_calling_thread_under_fifo(monkeypatch):
    calls = []
    monkeypatch.setattr(os, "SCHED_FIFO", 1, raising=False)
    monkeypatch.setattr(
        os, "sched_setscheduler", lambda pid, policy, param: calls.append((pid, policy, param)), raising=False
    )
    assert ask_for_realtime_priority(10) == 10
    ((pid, policy, param),) = calls
    assert (pid, policy, param.sched_priority) == (0, 1, 10)  # pid 0: the calling thread only


@pytest.mark.parametrize("error", [PermissionError(1, "Operation not permitted"), OSError(22, "Invalid argument")])
def test_a_refused_priority_leaves_the_fair_scheduler_and_says_why(monkeypatch, caplog, error):
    def refuse(*_):
        raise error

    monkeypatch.setattr(os, "SCHED_FIFO", 1, raising=False)
    monkeypatch.setattr(os, "sched_setscheduler", refuse, raising=False)
    with caplog.at_level(logging.INFO, logger="swarmloc.vehicle"):
        assert ask_for_realtime_priority(10) == 0
    assert "SCHED_FIFO priority 10 refused" in caplog.text and error.strerror in caplog.text


def test_a_platform_without_fifo_runs_the_fair_scheduler(monkeypatch, caplog):
    monkeypatch.delattr(os, "SCHED_FIFO", raising=False)
    with caplog.at_level(logging.INFO, logger="swarmloc.vehicle"):
        assert ask_for_realtime_priority(10) == 0
    assert "no SCHED_FIFO" in caplog.text
