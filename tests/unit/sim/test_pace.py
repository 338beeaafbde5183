"""The ticks a realtime vehicle hears: the first two, one a second, the final one."""

from sim.pace import on_pace


def test_the_pace_carries_the_first_ticks_one_a_second_and_the_final():
    heard = [t for t in range(0, 201) if on_pace(t, final=t == 187, ticks_per_second=50)]
    assert heard == [0, 1, 50, 100, 150, 187, 200]


def test_a_clock_slower_than_a_tick_a_second_paces_every_tick():
    assert all(on_pace(t, final=False, ticks_per_second=0) for t in range(10))
