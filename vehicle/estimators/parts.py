"""The kinds of part a vehicle ``Filter`` is composed of, one ``Protocol`` each (navlie's ``types.py``),
and what a measurement part is handed (``Fusing``). A part is given the state, the store and what it
needs, never the filter: parts can be read, tested and swapped one at a time.

| part | kind | what it does | built-in |
| --- | --- | --- | --- |
| ``gnss`` | :class:`GnssObservation` | how a fix observes the state; a prior's state | ``vehicle.models.gnss`` |
| ``motion`` | :class:`MotionModel` | the linearized step of the moving states | ``vehicle.models.motion`` |
| ``update`` | :class:`UpdateStrategy` | the prediction: linearized or unscented | ``updates`` |
| ``store`` | :class:`Store` | where x and P live, how they change | ``stores``, ``vehicle.estimators.centralized`` |
| ``divergence`` | :class:`DivergenceGuard` | a state no longer usable, and the fallback | ``divergence`` |
| ``errors`` | :class:`ErrorStates` | sensor errors that persist, as states | ``persisting_errors`` |
| ``sightings`` | :class:`MeasurementPart` | landmark sightings and camera frames | ``known_map``, ``vision_map`` |

A measurement part says which message kinds it takes (``handlers``); the filter hands each message to
the part registered for its type (``Filter.handle``), so a new sensor is a message, its part and one
registration (docs/tutorial/adding-a-sensor.md). Pure.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from bus import rejections
from vehicle.estimators.state import FilterState, Notice
from vehicle.models.cooperative import Correction
from vehicle.models.cooperative_fixes import CooperativeFix, SeenFix
from vehicle.models.gnss import Observed
from vehicle.models.gnss_error import GnssErrorModel
from vehicle.models.input_noise import InputNoise
from vehicle.models.kalman import UpdateResult

Say = Callable[[Notice], None]  # queue a notice for the vehicle to say (STATUSTEXT), once
Subject = tuple[str, int]  # ("landmark", id), ("robot", id seen) or ("seen", id of the robot seeing this one)
Decaying = tuple[int, np.ndarray, np.ndarray, int]  # first index, correlation times, stationary variances, end


class Store(Protocol):
    """Where x (n,) and P (n, n) live and how they change (vehicle.estimators.stores)."""

    dense: bool  # True: the closed-form 4-state prediction may replace x and P

    def move(self, s: FilterState, F: np.ndarray, Q: np.ndarray, x_next: np.ndarray) -> None: ...
    def update(
        self, s: FilterState, y: np.ndarray, H: np.ndarray, R: np.ndarray, gate: float, idx: list[int] | None = None
    ) -> UpdateResult: ...
    def correct(self, s: FilterState, correction: Correction) -> None: ...
    def append(self, s: FilterState, variances: np.ndarray) -> None: ...
    def drop(self, s: FilterState, indices: list[int]) -> None: ...
    def set_spread(self, s: FilterState, indices: list[int], variances: np.ndarray) -> None: ...
    def inflate(self, s: FilterState, indices: list[int], variances: np.ndarray) -> None: ...


class GnssObservation(Protocol):
    """How a GNSS fix observes the state (vehicle.models.gnss)."""

    error: GnssErrorModel | None
    base_dim: int

    def initial(self, pose: np.ndarray, covariance: np.ndarray, from_fixes: bool) -> tuple[np.ndarray, np.ndarray]: ...
    def observe(self, x: np.ndarray, reported_cov_m2: np.ndarray) -> Observed: ...


class MotionModel(Protocol):
    """The motion of the moving states (vehicle.models.motion)."""

    first_estimates: bool

    def pose_only(self, x: np.ndarray) -> bool: ...
    def base(
        self, x: np.ndarray, speed: float, rate: float, dt: float, noise: InputNoise
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...
    def step(
        self,
        x: np.ndarray,
        speed: float,
        rate: float,
        dt: float,
        noise: InputNoise,
        *,
        decaying: Decaying | None = None,
        prior_xy: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


class ErrorStates(Protocol):
    """Sensor errors that persist, as states after the base states (persisting_errors)."""

    per_subject: int

    def start(self, s: FilterState) -> None: ...
    def initialise(self, s: FilterState) -> None: ...
    def position_reset(self, s: FilterState) -> None: ...
    def recovered(self, s: FilterState) -> None: ...
    def decaying(self, s: FilterState) -> Decaying: ...
    def model(self, s: FilterState, first: int) -> dict[str, Any]: ...
    def index_of(self, s: FilterState, store: Store, key: Subject, t_us: int, bearing_var: float) -> int: ...
    def of_sighting(self, s: FilterState, store: Store, key: Subject, t_us: int, bearing_var: float) -> dict: ...
    def of_fix(self, s: FilterState, store: Store, fix: CooperativeFix | SeenFix) -> dict | None: ...


class UpdateStrategy(Protocol):
    """The prediction over one interval of held inputs (updates): linearized or unscented."""

    unscented_fixes: bool  # neighbours' fixes through sigma points of the pose

    def predict(
        self,
        s: FilterState,
        store: Store,
        motion: MotionModel,
        errors: ErrorStates | None,
        speed: float,
        rate: float,
        dt: float,
        noise: InputNoise,
    ) -> None: ...


class DivergenceGuard(Protocol):
    """When a state is no longer usable, and what to fall back to (divergence)."""

    def diverged(self, s: FilterState) -> bool: ...
    def remember(self, s: FilterState, t_us: int) -> None: ...
    def inflated(self, P: np.ndarray, gnss: GnssObservation) -> np.ndarray: ...


@dataclass
class Fusing:
    """What a measurement part is handed with a message: the state and the store it changes, the
    persisting errors' part (if any), the gate of two-dimensional updates, how to bring the state to a
    stamp (the part decides whether a message moves the state at all), and what to say a notice with."""

    state: FilterState
    store: Store
    errors: ErrorStates | None
    gate: float
    propagate_to: Callable[[int], None]
    say: Say


Handler = Callable[[Fusing, Any], None]
Reject = rejections.Reject  # reject(reason, where, detail): counts input a part refuses


class Replayable(Protocol):
    """An estimator as the fusion horizon (vehicle.process.fusion) drives it: measurements in stamp
    order, one cycle per loop period, and snapshots to go back to when a measurement comes late."""

    def handle(self, msg: Any) -> None: ...
    def handle_row(self, topic: str, stamp_us: int, row: list[float], message: Callable[[], Any]) -> None: ...
    def cycle(self, t_us: int) -> None: ...
    def snapshot(self) -> Any: ...
    def restore(self, snapshot: Any) -> None: ...


class MeasurementPart(Protocol):
    """A part that fuses messages of its own kinds (landmark sightings, camera frames...), keeps a book
    in the state (``FilterState.landmarks``) and follows the state's life."""

    def handlers(self) -> dict[type, Handler]: ...
    def start(self, s: FilterState) -> None: ...
    def initialise(self, s: FilterState) -> None: ...
    def position_reset(self, s: FilterState) -> None: ...
    def recovered(self, s: FilterState) -> None: ...
    def landmark_map(self, s: FilterState) -> tuple[np.ndarray, np.ndarray] | None: ...


class BooklessPart:
    """The state's life for a measurement part that keeps no book in the state (a sensor added by the
    recipe whose updates touch only the filter's own rows): nothing to start, initialise, reset or
    recover, and no map."""

    def start(self, s: FilterState) -> None: ...
    def initialise(self, s: FilterState) -> None: ...
    def position_reset(self, s: FilterState) -> None: ...
    def recovered(self, s: FilterState) -> None: ...

    def landmark_map(self, s: FilterState) -> None:
        return None
