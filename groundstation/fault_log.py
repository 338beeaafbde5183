"""Logs the physical fault plan as events: added at the start of the run, then started and expired
as sim time passes (the world applies them at the same sim times)."""

from __future__ import annotations

from typing import Any, Callable


def fault_fields(fault: Any) -> dict[str, Any]:
    """The event fields of one fault: its name, kind ("fault") and parameters (with "zone" if it has one)."""
    fields = fault.model_dump(mode="json", exclude={"name", "kind", "center_m", "radius_m"})
    fields.update(name=fault.name, fault=fault.kind)
    if hasattr(fault, "zone"):
        fields["zone"] = fault.zone()
    return fields


class FaultLog:
    def __init__(self, faults: tuple, log: Callable[..., None]) -> None:
        self.faults, self._log = faults, log
        self._started: set[str] = set()
        self._ended: set[str] = set()
        self._announced = False

    def advance(self, stamp_us: int) -> None:
        """Log every change of the plan's state up to ``stamp_us`` (call once per clock tick)."""
        if not self._announced:
            for f in self.faults:
                self._log("fault_added", 0, **fault_fields(f))
            self._announced = True
        t_s = stamp_us * 1e-6
        for f in self.faults:
            if f.name not in self._started and t_s >= f.start_s:
                self._started.add(f.name)
                self._log("fault_started", round(f.start_s * 1e6), name=f.name, fault=f.kind)
            if f.name not in self._ended and f.for_s is not None and t_s >= f.start_s + f.for_s:
                self._ended.add(f.name)
                self._log("fault_expired", round((f.start_s + f.for_s) * 1e6), name=f.name, fault=f.kind)
