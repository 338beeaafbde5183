"""The ground station owns the fault plan: it validates changes, answers queries, and logs every
change and every start and end of a fault as an event (stamped in sim time).

Pure: no bus. The node feeds it requests and clock times and publishes the plan it returns.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from bus.faults import check_fault, named
from bus.plan import FaultPlan, FaultReply, FaultRequest, FaultState

MAX_FAULTS = 256  # a plan larger than this is refused: every process holds and checks it per packet


def fault_fields(fault: Any) -> dict[str, Any]:
    """The event fields of one fault: its name, kind ("fault") and parameters (with "zone" if it has one)."""
    fields = fault.model_dump(mode="json", exclude={"name", "kind", "center_m", "radius_m"})
    fields.update(name=fault.name, fault=fault.kind)
    if hasattr(fault, "zone"):
        fields["zone"] = fault.zone()
    return fields


def describe(fault: Any) -> str:
    """One line of the fault's parameters, as `swarm fault list` prints it."""
    skip = {"name", "kind", "start_s", "for_s"}
    parts = [f"{k}={v}" for k, v in fault.model_dump(mode="json").items() if k not in skip and v not in (None, "*")]
    window = f"from {fault.start_s:g} s" + (f" for {fault.for_s:g} s" if fault.for_s is not None else "")
    return " ".join(parts + [window])


class FaultControl:
    """The plan, its version, and the event log of its changes."""

    def __init__(self, faults: tuple, *, vehicles: int, log: Callable[..., None]) -> None:
        self.vehicles, self._log = vehicles, log
        self.faults: list = list(faults)
        self.version = 0
        self.now_us = 0
        self._started: set[str] = set()
        self._ended: set[str] = set()
        self._announced = False

    def resume(self, stamp_us: int) -> None:
        """A restarted ground station: the plan was announced by its predecessor, and what had
        started or ended by ``stamp_us`` was logged already."""
        self._announced = True
        t_s = stamp_us * 1e-6
        self._started = {f.name for f in self.faults if t_s >= f.start_s}
        self._ended = {f.name for f in self.faults if (_end_s(f) is not None and t_s >= _end_s(f))}
        self.now_us = stamp_us

    def plan(self) -> FaultPlan:
        return FaultPlan(version=self.version, faults=tuple(self.faults))

    def advance(self, stamp_us: int) -> None:
        """Log every start and end of a fault up to ``stamp_us`` (call once per clock tick)."""
        self.now_us = stamp_us
        if not self._announced:
            for f in self.faults:
                self._log("fault_added", 0, **fault_fields(f))
            self._announced = True
        t_s = stamp_us * 1e-6
        for f in self.faults:
            if f.name not in self._started and t_s >= f.start_s:
                self._started.add(f.name)
                self._log("fault_started", round(f.start_s * 1e6), name=f.name, fault=f.kind)
            end_s = _end_s(f)
            if f.name not in self._ended and end_s is not None and t_s >= end_s:
                self._ended.add(f.name)
                self._log("fault_expired", round(end_s * 1e6), name=f.name, fault=f.kind)

    def request(self, req: FaultRequest) -> FaultReply:
        """Apply one request; a rejected one changes nothing and says why."""
        try:
            if req.op == "add":
                self._add(req)
            elif req.op == "remove":
                self._remove(req.name)
            elif req.op == "clear":
                for f in list(self.faults):
                    self._remove(f.name)
        except ValueError as exc:
            return self._reply(False, str(exc))
        return self._reply(True)

    def _add(self, req: FaultRequest) -> None:
        if req.fault is None:
            raise ValueError("add needs a fault")
        if len(self.faults) >= MAX_FAULTS:
            raise ValueError(f"the plan holds {MAX_FAULTS} faults already; remove some first")
        fault = req.fault
        if req.relative:
            fault = fault.model_copy(update={"start_s": round(self.now_us * 1e-6 + fault.start_s, 6)})
        if fault.name and any(f.name == fault.name for f in self.faults):
            raise ValueError(f"a fault named {fault.name!r} exists already")
        check_fault(fault, self.vehicles)
        fault = named([fault], {f.name for f in self.faults})[0]
        self.faults.append(fault)
        self.version += 1
        self._log("fault_added", self.now_us, **fault_fields(fault))

    def _remove(self, name: str | None) -> None:
        match = [f for f in self.faults if f.name == name]
        if not match:
            known = ", ".join(f.name for f in self.faults) or "none"
            raise ValueError(f"no fault named {name!r} (faults: {known})")
        self.faults.remove(match[0])
        self.version += 1
        self._log("fault_removed", self.now_us, name=name, fault=match[0].kind)

    def _reply(self, ok: bool, error: str = "") -> FaultReply:
        t_s = self.now_us * 1e-6
        states = tuple(
            FaultState(name=f.name, kind=f.kind, state=_state(f, t_s), description=describe(f)) for f in self.faults
        )
        return FaultReply(ok=ok, error=error, sim_time_s=t_s, plan=self.plan(), states=states)


def _end_s(fault: Any) -> float | None:
    if getattr(fault, "kind", "") == "kill":
        return None if fault.restart_after_s is None else fault.start_s + fault.restart_after_s
    return None if fault.for_s is None else fault.start_s + fault.for_s


def _state(fault: Any, t_s: float) -> str:
    end = _end_s(fault)
    if t_s < fault.start_s:
        return "pending"
    return "expired" if end is not None and t_s >= end else "active"
