"""The ground station's wait at the end of a run (groundstation.station_loop._await_final_data): keys
are not ordered among each other, so the world's end can overtake what was sent before it. The wait
holds until every completed vehicle's last frames and final status, and the truth of every tick up
to the end's, are in; a deadline guards against a bus that lost them."""

from __future__ import annotations

import logging
from types import SimpleNamespace

from bus import messages as m
from bus.config import build_config
from groundstation.station_loop import _await_final_data


class _LateMailbox:
    """Gives nothing for ``empty_gets`` calls, then its items: what is still on its way at the end."""

    def __init__(self, items: list, empty_gets: int) -> None:
        self.items, self.empty_gets = list(items), empty_gets

    def get(self, timeout: float | None = None):
        if self.empty_gets > 0:
            self.empty_gets -= 1
            return None
        return self.items.pop(0) if self.items else None

    def get_nowait(self):
        return None if self.empty_gets > 0 or not self.items else self.items.pop(0)


def _station(end: m.RunEnd, mailbox: _LateMailbox, truth_tick: int) -> SimpleNamespace:
    """A ground station whose completed vehicles' frames and final statuses are all in."""
    gs = SimpleNamespace(
        ended=end,
        config=build_config({}),
        intake=SimpleNamespace(stream_stamp_us={vid: end.stamp_us for vid in end.completed}),
        reports=SimpleNamespace(statuses={vid: SimpleNamespace(final=True) for vid in end.completed}),
        mailbox=mailbox,
        truth_tick=truth_tick,
    )

    def handle(item) -> None:
        gs.truth_tick = max(gs.truth_tick, item.tick)  # the items here are truth batches

    gs.handle = handle
    return gs


def test_the_last_ticks_truth_still_on_its_way_is_waited_for():
    end = m.RunEnd(tick=81, stamp_us=40_000_000, vehicles_alive=3, completed=(1, 2, 3))
    mailbox = _LateMailbox([SimpleNamespace(tick=80), SimpleNamespace(tick=81)], empty_gets=3)
    gs = _station(end, mailbox, truth_tick=79)
    _await_final_data(gs, timeout_s=5.0)
    assert gs.truth_tick == 81


def test_truth_that_never_comes_ends_the_wait_at_the_deadline_and_says_so(caplog):
    end = m.RunEnd(tick=81, stamp_us=40_000_000, vehicles_alive=3, completed=(1, 2, 3))
    gs = _station(end, _LateMailbox([], empty_gets=0), truth_tick=79)
    with caplog.at_level(logging.WARNING, logger="swarmloc.groundstation"):
        _await_final_data(gs, timeout_s=0.3)
    assert gs.truth_tick == 79
    assert "truth of ticks 80..81 did not arrive" in caplog.text
