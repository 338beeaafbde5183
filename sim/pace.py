"""Which clock ticks a realtime vehicle hears (``ctl/pace``), where the ground station hears every
one (``ctl/clock``).

A realtime vehicle cycles on its own wall-clock deadlines, mapped from sim time by the world's first
paced tick; of the ticks after it, it only needs the final one (vehicle.process.loops.run_realtime). Fifty
ticks a second to every vehicle were a wake-up of its bus thread and its loop, and a decode, each 20
ms: in a 20-vehicle, 20 s run on two cores, 2 s of its 31 s of CPU
(docs/decisions/performance.md, fifteenth pass). The pace carries the first tick (each vehicle's
first cycle), the second (the first the world paces, which every deadline is taken from), the tick
of every full second (a restarted vehicle maps its deadlines by the first tick it hears), and the
final one. A lockstep vehicle waits for every tick and hears ``ctl/clock``.
"""

from __future__ import annotations


def on_pace(tick: int, *, final: bool, ticks_per_second: int) -> bool:
    """Whether clock tick number ``tick`` (``final``: the run's last) also goes out on the pace of a
    realtime swarm whose clock ticks ``ticks_per_second`` times a second."""
    return final or tick <= 1 or tick % max(1, ticks_per_second) == 0
