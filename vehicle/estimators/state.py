"""The state of a vehicle estimator: one object holding everything a fusion-horizon replay must
restore (navlie's ``State``, grown by what a real vehicle filter carries besides mean and covariance).

``FilterState.copy`` is the only snapshot there is, and it copies every field by one rule
(``copied``), so nothing can be left off a hand-kept list:

- numbers, strings, tuples and frozen dataclasses are immutable: shared;
- a numpy array is copied, unless it is read-only: a read-only array is shared, and numpy itself
  raises if anyone writes to it (the landmark descriptors of a SLAM map are large and only ever
  replaced by a grown copy, so they are kept read-only and never copied);
- lists, dicts and sets are copied one level deep (their entries are immutable values);
- an object with a ``copy()`` method is copied by it (held inputs, the GNSS health monitor);
- a mutable dataclass without one is copied field by field by the same rule (the models' books);
- anything else is refused with a TypeError when the state is first copied.

What a replay must *not* undo lives outside the state, on the estimator: notices already given,
front-end results cached by frame, the floor of the reset counter.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass, field
from typing import Any, TypeVar

import numpy as np

from bus.config import SensorSpec
from bus.consistency import NisBook
from vehicle.estimators.adaptive import NoiseAdaptation
from vehicle.estimators.alignment import GnssAlignment
from vehicle.estimators.gnss_health import GnssHealth, GnssHealthSpec
from vehicle.estimators.inputs import HeldInput
from vehicle.estimators.wheel_slip import SlipGuard
from vehicle.models.kalman import UpdateResult
from vehicle.trust.neighbours import NeighbourBook

T = TypeVar("T")
_IMMUTABLE = (int, float, complex, str, bytes, bool, tuple, frozenset, type(None))
SEVERITY_WARNING, SEVERITY_INFO = 4, 6  # MAV_SEVERITY of a notice


@dataclass(frozen=True)
class Notice:
    """Something the vehicle should say (STATUSTEXT), stamped in sim time; ``status_changed`` asks
    for an ESTIMATOR_STATUS at once (GNSS health). Given once, on the estimator: a replay does not
    undo it."""

    stamp_us: int
    severity: int
    text: str
    status_changed: bool = False


class Notices:
    """The notices an estimator has to say, each said once: a replay re-runs cycles that said
    something already (what a replay must not undo lives here, outside the state)."""

    def __init__(self) -> None:
        self._queued: list[Notice] = []
        self._said_until_us = -1

    def say(self, notice: Notice) -> None:
        """Queue ``notice`` unless one at its stamp or later was taken already."""
        if notice.stamp_us > self._said_until_us:
            self._queued.append(notice)

    def take(self) -> list[Notice]:
        out, self._queued = self._queued, []
        if out:
            self._said_until_us = max(self._said_until_us, *(n.stamp_us for n in out))
        return out


@dataclass
class EstimatorCounters:
    """Cumulative counts an estimator reports (VehicleStatus)."""

    gnss_accepted: int = 0
    gnss_rejected: int = 0
    stale: int = 0
    resets: int = 0
    v2v_fused: int = 0
    v2v_rejected: int = 0
    v2v_distrusted: int = 0  # neighbours' fixes not fused because the neighbour was distrusted
    landmarks: int = 0  # SLAM: landmarks in the map; known-map: landmarks in the surveyed map
    landmarks_updated: int = 0  # SLAM: landmarks the last usable camera frame updated
    frames_used: int = 0  # SLAM: camera frames through the front end
    nis: NisBook = field(default_factory=NisBook)  # NIS of the fused updates per kind (immutable: shared by copies)


@dataclass
class FilterState:
    """Mean ``x`` (n,) and covariance ``P`` (n, n) (None before the first prior or alignment), the
    time they stand at, the inputs held since then, the GNSS monitors, the divergence fallback, and
    the books of the models that keep any (``landmarks``: the map's, ``errors``: the sighting error
    states')."""

    speed: HeldInput
    gyro: HeldInput
    odom_yaw: HeldInput
    slip: SlipGuard
    gnss_health: GnssHealth
    alignment: GnssAlignment
    iae: NoiseAdaptation | None = None
    x: np.ndarray | None = None
    P: np.ndarray | None = None
    time_us: int = 0
    counters: EstimatorCounters = field(default_factory=EstimatorCounters)
    last_good: tuple[np.ndarray, np.ndarray] | None = None  # (x, P), read-only: shared by copies
    good_until_us: int = -1  # the fallback is refreshed from then on
    prior_xy: np.ndarray | None = None  # position as last propagated, before any update (first estimates)
    neighbours: NeighbourBook = field(default_factory=NeighbourBook)  # which neighbours it believes
    visual_us: int = -1  # stamp of the latest visual odometry (it then gives the yaw rate, not the gyro)
    landmarks: Any = None
    errors: Any = None

    def copy(self) -> FilterState:
        """An independent copy (module docstring)."""
        return _fieldwise(self)

    @classmethod
    def fresh(cls, spec: SensorSpec, gate_probability: float, adaptive_window: int) -> FilterState:
        """The state of a filter for the sensors of ``spec`` before its prior: each input held with its
        sensor's period, the GNSS monitor at the filter's gate, IAE on when ``adaptive_window`` > 0."""
        odom_period_us, gyro_period_us = round(1e6 / spec.odom_rate_hz), round(1e6 / spec.imu_rate_hz)
        return cls(
            speed=HeldInput(period_us=odom_period_us),
            gyro=HeldInput(period_us=gyro_period_us),
            odom_yaw=HeldInput(period_us=odom_period_us),
            slip=SlipGuard.for_datasheet(spec.odom_speed_sigma_mps, spec.imu_rate_hz),
            gnss_health=GnssHealth(GnssHealthSpec(gate_probability=gate_probability)),
            alignment=GnssAlignment(),
            iae=NoiseAdaptation(adaptive_window) if adaptive_window else None,
            counters=EstimatorCounters(),
        )


def tally_nis(s: FilterState, kind: str, result: UpdateResult, dof: int) -> None:
    """Count a fused update's NIS of ``dof`` dimensions under ``kind`` (bus.consistency.NIS_KINDS)."""
    if result.accepted:
        s.counters.nis = s.counters.nis.add(kind, result.nis, dof)


def copied(value: T) -> T:
    """``value`` copied by the module docstring's rule."""
    if isinstance(value, _IMMUTABLE):
        return value
    if isinstance(value, np.ndarray):
        return value if not value.flags.writeable else value.copy()
    if isinstance(value, (list, dict, set)):
        return type(value)(value)
    copy = getattr(value, "copy", None)
    if callable(copy):
        return copy()
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return value if value.__dataclass_params__.frozen else _fieldwise(value)
    raise TypeError(f"the filter state cannot copy a {type(value).__name__}: give it a copy() method")


def _fieldwise(value: T) -> T:
    """A mutable dataclass copied field by field with :func:`copied`."""
    twin = object.__new__(type(value))
    for name in _field_names(type(value)):
        object.__setattr__(twin, name, copied(getattr(value, name)))
    return twin


@functools.cache
def _field_names(cls: type) -> tuple[str, ...]:
    """The fields of dataclass ``cls`` (looked up once per class: a state is copied at every checkpoint)."""
    return tuple(f.name for f in dataclasses.fields(cls))


def frozen(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only (in place) and returned: states share it instead of copying it."""
    array.setflags(write=False)
    return array
