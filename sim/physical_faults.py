"""Applies the plan's physical faults to the world's sensor output: what each kind silences and whose
radio it cuts (the kinds' own ``silences`` and ``jams_comms``, bus.faults), and the spoofers' offsets,
which grow from the moment each vehicle is captured. Pure and deterministic: a function of sim time
and the vehicles' true poses."""

from __future__ import annotations

import numpy as np

from bus.faults import PHYSICAL_KINDS, SpoofGnss


class PhysicalFaults:
    def __init__(self, faults: tuple = ()) -> None:
        self.faults = tuple(f for f in faults if f.kind in PHYSICAL_KINDS)
        self._captured_us: dict[tuple[int, str], int] = {}  # (vehicle, spoof fault) -> capture time

    def replace(self, faults: tuple) -> None:
        """A new plan (from the ground station); capture times of spoofers that remain are kept."""
        self.faults = tuple(f for f in faults if f.kind in PHYSICAL_KINDS)
        names = {f.name for f in faults}
        self._captured_us = {k: v for k, v in self._captured_us.items() if k[1] in names}

    def silenced(self, vehicle_id: int, sensor: str, t_us: int, pose: np.ndarray) -> bool:
        """True when ``sensor`` of ``vehicle_id`` produces nothing at ``t_us`` (blackout or jamming)."""
        t_s = t_us * 1e-6
        return any(f.active(t_s) and f.silences(vehicle_id, sensor, pose[:2]) for f in self.faults)

    def comm_jammed(self, t_us: int, pose: np.ndarray) -> bool:
        """True when a vehicle at ``pose`` is inside an active comm-jamming zone."""
        return any(f.active(t_us * 1e-6) and f.jams_comms(pose[:2]) for f in self.faults)

    def spoof_offset_m(self, vehicle_id: int, t_us: int, pose: np.ndarray) -> np.ndarray:
        """(2,) metres added to the fix: drift_mps times the time since the vehicle was captured."""
        offset = np.zeros(2)
        for f in self.faults:
            if not isinstance(f, SpoofGnss):
                continue
            key = (vehicle_id, f.name)
            if not (f.active(t_us * 1e-6) and f.inside(pose[:2])):
                self._captured_us.pop(key, None)
                continue
            captured = self._captured_us.setdefault(key, t_us)
            heading = np.deg2rad(f.heading_deg)
            offset += f.drift_mps * (t_us - captured) * 1e-6 * np.array([np.cos(heading), np.sin(heading)])
        return offset
