"""What every added sensor declares (bus.sensors), once, so that every process agrees on it and the
rest is derived:

- ``topic``: its name on the wire, in a batch's blocks, in link-fault globs and blackouts;
- ``width``, ``max_rows``, ``max_abs``: a row's values, how many rows a batch may carry, their bound
  (the feed's common checks: bus.feed_blocks), ``several`` whether one stamp may carry several rows
  (a camera frame's points; else one sample per stamp), and ``flaw`` for checks of its own;
- ``message``: the typed message a row becomes (what the vehicle's filter hands its part);
- ``Spec``: its section of the datasheet (``sensors.<topic>``; ``rate_hz`` 0: the sensor is off);
- ``world_model``: what the world measures it with (``"module:name"``, in sim/): a function
  ``(pose, spec, rng) -> row``, or a class built once from the swarm's configuration whose
  ``measure(vehicle_id, t_us, pose, spec, rng)`` returns the rows (k, width) of one measurement (a
  sensor that keeps state, or sees many things at once);
- ``part``: the function that builds the filter part that fuses it (``"module:function"``, in
  vehicle/estimators/): every estimator of a vehicle whose datasheet has the sensor on gets it.

The feeds that predate the registry (the IMU, odometry, GNSS, the prior, ranging, sightings, camera
frames) are wired by hand in bus.feed and sim.world.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from bus.strict_model import Strict


class SensorSpec(Strict):
    """The datasheet section every added sensor has: how often it measures (0: off)."""

    rate_hz: float = 0.0


class SensorKind:
    topic: ClassVar[str]
    width: ClassVar[int]
    max_rows: ClassVar[int]
    max_abs: ClassVar[float]
    several: ClassVar[bool] = False
    Spec: ClassVar[type[SensorSpec]]
    world_model: ClassVar[str]
    part: ClassVar[str]

    @classmethod
    def message(cls, vehicle_id: int, stamp_us: int, seq: int, row: np.ndarray) -> Any:
        raise NotImplementedError

    @classmethod
    def flaw(cls, rows: np.ndarray) -> str | None:
        """What is wrong with rows (k, width) beyond the common checks (None: nothing)."""
        return None


def resolve(path: str) -> Any:
    """The object ``"module:name"`` names (a sensor's world model or filter part)."""
    import importlib

    module, _, name = path.partition(":")
    return getattr(importlib.import_module(module), name)
