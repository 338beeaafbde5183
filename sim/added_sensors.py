"""The sensors added by the sensor recipe (bus.sensors), measured by the world: each one whose
datasheet section is on (``rate_hz`` > 0), at its rate, by its model (``world_model``: a function of
the true pose giving one row, or a class built once from the configuration whose ``measure`` gives a
measurement's rows), from the vehicle's true pose, unless a fault silences it. Each vehicle draws
each added sensor's noise from a generator of its own (seeded by the world's seed, the vehicle and
the sensor's name), so turning one on leaves every other noise stream of the world bit-identical."""

from __future__ import annotations

import zlib
from collections.abc import Callable

import numpy as np

from bus.config import SwarmConfig
from bus.sensors import SENSORS
from bus.sensors.base import resolve

Emit = Callable[[int, str, np.ndarray], None]  # (vehicle id, topic, row) at the step's stamp
Silenced = Callable[[int, str], bool]  # whether a fault silences (vehicle id, topic) now


class AddedSensors:
    def __init__(self, config: SwarmConfig, vehicle_ids: list[int], step_us: int) -> None:
        self._sensors = []
        for kind in SENSORS:
            spec = getattr(config.sensors, kind.topic)
            if spec.rate_hz > 0:
                period_us = max(step_us, round(1e6 / spec.rate_hz / step_us) * step_us)
                rngs = {
                    vid: np.random.default_rng([config.world.seed, vid, zlib.crc32(kind.topic.encode())])
                    for vid in vehicle_ids
                }
                model = resolve(kind.world_model)
                if isinstance(model, type):  # a model with state of its own: its rows per measurement
                    model = model(config).measure
                else:
                    model = _one_row(model)
                self._sensors.append((kind.topic, model, spec, period_us, rngs))

    @property
    def topics(self) -> tuple[str, ...]:
        return tuple(topic for topic, *_ in self._sensors)

    def measure(self, t_us: int, vehicle_ids: list[int], poses: np.ndarray, silenced: Silenced, emit: Emit) -> None:
        """Every added sensor due at ``t_us``, of every vehicle at its true pose (N, 3)."""
        for topic, model, spec, period_us, rngs in self._sensors:
            if t_us % period_us:
                continue
            for vid, pose in zip(vehicle_ids, poses):
                rows = model(vid, t_us, pose, spec, rngs[vid])  # drawn even when silenced: faults shift no noise
                if not silenced(vid, topic):
                    for row in rows:
                        emit(vid, topic, row)


def _one_row(function: Callable) -> Callable:
    """A world model ``(pose, spec, rng) -> row`` as a measurement's rows."""

    def measure(vehicle_id: int, t_us: int, pose: np.ndarray, spec, rng: np.random.Generator) -> np.ndarray:
        return function(pose, spec, rng)[None, :]

    return measure
