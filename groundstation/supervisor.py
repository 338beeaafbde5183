"""What the supervisor (`swarm up`) must do about the fault plan's ``kill`` faults at a sim time:
SIGKILL a vehicle process when its kill starts, start it again ``restart_after_s`` later. Pure."""

from __future__ import annotations

from dataclasses import dataclass, field

from bus.faults import Kill


@dataclass
class KillSchedule:
    faults: tuple = ()
    killed: set[str] = field(default_factory=set)
    restarted: set[str] = field(default_factory=set)

    def set_plan(self, faults: tuple) -> None:
        self.faults = tuple(f for f in faults if isinstance(f, Kill))

    def due(self, now_us: int) -> list[tuple[str, int, str]]:
        """Actions due at ``now_us``: ("kill" | "restart", vehicle id, fault name), each once."""
        t_s, actions = now_us * 1e-6, []
        for f in self.faults:
            if f.name not in self.killed and t_s >= f.start_s:
                self.killed.add(f.name)
                actions.append(("kill", f.vehicle, f.name))
            if (f.name in self.killed and f.name not in self.restarted and f.restart_after_s is not None
                    and t_s >= f.start_s + f.restart_after_s):
                self.restarted.add(f.name)
                actions.append(("restart", f.vehicle, f.name))
        return actions
