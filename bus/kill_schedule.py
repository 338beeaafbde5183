"""When the fault plan's ``kill`` faults act, in sim time: the vehicle process is SIGKILLed on the first
clock tick at or past ``start_s`` and started again on the first tick at or past
``start_s + restart_after_s``. The supervisor (`swarm up`) executes these actions; in lockstep the
world holds its clock at the same ticks until they have happened. Pure."""

from __future__ import annotations

from dataclasses import dataclass, field

from bus.faults import Kill


@dataclass
class KillSchedule:
    faults: tuple[Kill, ...] = ()
    killed: set[str] = field(default_factory=set)
    restarted: set[str] = field(default_factory=set)

    def set_plan(self, faults: tuple) -> None:
        self.faults = tuple(f for f in faults if isinstance(f, Kill))

    def due(self, now_us: int) -> list[tuple[str, int, str]]:
        """Actions due at ``now_us``: ("kill" | "restart", vehicle id, fault name), each once."""
        actions = []
        for f in self.faults:
            if f.name not in self.killed and now_us >= f.kill_us():
                self.killed.add(f.name)
                actions.append(("kill", f.vehicle, f.name))
            restart_us = f.restart_us()
            if (
                f.name in self.killed
                and f.name not in self.restarted
                and restart_us is not None
                and now_us >= restart_us
            ):
                self.restarted.add(f.name)
                actions.append(("restart", f.vehicle, f.name))
        return actions
