"""Sensor errors that persist, as states after the base states (vehicle.models.added_states), each on
when its datasheet field is nonzero:

- the wheel odometry's speed and yaw-rate scale errors (two states, prior sigma
  ``odom_scale_prior_sigma``, a slow random walk);
- the camera's range scale (one state, ``range_scale_prior_sigma``, ``known-map`` only): a camera
  that reads range from a target's size reads every target a few per cent long or short;
- per sighted subject (a landmark, a robot seen, a robot that sees this one) a Gauss-Markov state for
  the range error (a fraction ``range_correlated_sigma_per_m`` of the range, correlation time
  ``range_correlation_s``) and one for the bearing error (a fraction ``bearing_correlated_fraction``
  of the sighting's reported bearing variance, ``bearing_correlation_s``); the sighting model is
  ``added_states.persisting_sighting``.

Two ways to keep the subjects' states: ``GrowingErrors`` (``known-map``) adds a subject's states when
it is first seen and drops (marginalizes) them once it has not been seen for ``FORGET_AFTER``
correlation times; ``SlottedErrors`` (``ekf-slam``, whose map follows these states) keeps
``ERROR_SLOTS`` slots: a subject seen again gets its slot back, a new one takes a free slot or the
one of the subject seen longest ago (reset to 0 with the stationary variances: by then its states
hardly correlate with a new reading). Their books live in ``FilterState.errors``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from bus.config import SensorSpec
from vehicle.estimators.parts import Store, Subject
from vehicle.estimators.state import FilterState, frozen
from vehicle.models import added_states
from vehicle.models.cooperative_fixes import CooperativeFix, SeenFix

FORGET_AFTER = 5.0  # correlation times unseen before a subject's states are dropped (GrowingErrors)
ERROR_SLOTS = 8  # subjects in view at once, with their recent past (SlottedErrors)


class _SightingErrors:
    """What both ways share: the subjects' states and the sighting model's arguments."""

    def __init__(self, spec: SensorSpec, *, first_index: int, range_scale_index: int | None) -> None:
        self.range_sigma, self.range_tau = spec.range_correlated_sigma_per_m, spec.range_correlation_s
        self.bearing_fraction, self.bearing_tau = spec.bearing_correlated_fraction, spec.bearing_correlation_s
        self.per_subject = int(bool(self.range_sigma)) + int(bool(self.bearing_fraction))
        self.wheel_scale_sigma = spec.odom_scale_prior_sigma
        self.range_scale_sigma = spec.range_scale_prior_sigma if range_scale_index is not None else 0.0
        self.first = first_index  # the first subject state
        self.range_scale_index = range_scale_index

    def subject_states(self, bearing_var: float) -> list[tuple[float, float]]:
        """(tau s, stationary variance) of one subject's error states, in order (range, then bearing),
        for sightings reporting bearing variance ``bearing_var`` (rad^2)."""
        return ([(self.range_tau, self.range_sigma**2)] if self.range_sigma else []) + (
            [(self.bearing_tau, self.bearing_fraction * bearing_var)] if self.bearing_fraction else []
        )

    def scale_variances(self) -> list[float]:
        """Prior variances of the scale states (wheels, then the camera's range), in order."""
        return [self.wheel_scale_sigma**2] * (2 if self.wheel_scale_sigma else 0) + (
            [self.range_scale_sigma**2] if self.range_scale_sigma else []
        )

    def model(self, s: FilterState, first: int) -> dict:
        """``added_states.persisting_sighting``'s state arguments for the subject whose states start
        at ``first``."""
        model: dict = {}
        if self.range_sigma:
            model.update(range_state=first, range_sigma_per_m=self.range_sigma)
        if self.bearing_fraction:
            b = first + int(bool(self.range_sigma))
            model.update(bearing_state=b, bearing_var=self.stationary_variance(s, b))
        return model

    def of_sighting(self, s: FilterState, store: Store, key: Subject, t_us: int, bearing_var: float) -> dict:
        """The sighting model's state arguments for a sighting of ``key`` at ``t_us`` (its states
        added or handed a slot if need be); the camera's range scale included where there is one."""
        model = self.model(s, self.index_of(s, store, key, t_us, bearing_var)) if self.per_subject else {}
        if self.range_scale_index is not None:
            model["scale_state"] = self.range_scale_index
        return model

    def of_fix(self, s: FilterState, store: Store, fix: CooperativeFix | SeenFix) -> dict | None:
        """A robot sighting's persisting errors as states (vehicle.models.cooperative): the same
        camera's as a landmark's, one set per robot seen and one per robot that sees this one; this
        robot's own sightings are read with its camera's range scale too."""
        model = {}
        if self.per_subject:
            key = ("robot", fix.target_id) if isinstance(fix, CooperativeFix) else ("seen", fix.observer_id)
            model = self.model(s, self.index_of(s, store, key, fix.stamp_us, float(fix.covariance[1, 1])))
        if isinstance(fix, CooperativeFix) and self.range_scale_index is not None:
            model["scale_state"] = self.range_scale_index
        return model or None

    def index_of(self, s: FilterState, store: Store, key: Subject, t_us: int, bearing_var: float) -> int:
        raise NotImplementedError

    def stationary_variance(self, s: FilterState, index: int) -> float:
        raise NotImplementedError

    def position_reset(self, s: FilterState) -> None:
        """A GNSS reset of the position: nothing to do."""

    def recovered(self, s: FilterState) -> None:
        """After a divergence recovery: nothing to do (the book is kept)."""


@dataclass
class GrowingBook:
    states: dict[Subject, int] = field(default_factory=dict)  # subject -> index of its first state
    last_seen_us: dict[Subject, int] = field(default_factory=dict)
    decaying: list[tuple[float, float]] = field(default_factory=list)  # (tau s, variance) per state, in order


class GrowingErrors(_SightingErrors):
    """The subjects' states added when first seen, dropped when forgotten (module docstring)."""

    def start(self, s: FilterState) -> None:
        s.errors = GrowingBook()

    def initialise(self, s: FilterState) -> None:
        """A fresh book; the scale states appended after the base states (to the fresh state itself:
        a joint store takes the whole initialised state as its block)."""
        s.errors = GrowingBook()
        if self.scale_variances():
            s.x, s.P = added_states.append_states(s.x, s.P, np.array(self.scale_variances()))

    def decaying(self, s: FilterState) -> tuple[int, np.ndarray, np.ndarray, int]:
        """(first subject state, their correlation times, stationary variances, len(x))."""
        taus, variances = (np.array([d[i] for d in s.errors.decaying]) for i in (0, 1))
        return self.first, taus, variances, len(s.x)

    def stationary_variance(self, s: FilterState, index: int) -> float:
        return s.errors.decaying[index - self.first][1]

    def index_of(self, s: FilterState, store: Store, key: Subject, t_us: int, bearing_var: float) -> int:
        """The index of the first error state (range, then bearing) of the sighted subject ``key``,
        added (at 0, stationary variance: the bearing's a fraction of ``bearing_var``, the
        sighting's reported one) when it has none; the states of subjects unseen for FORGET_AFTER
        correlation times are dropped first."""
        book = s.errors
        book.last_seen_us[key] = t_us
        if key in book.states:
            return book.states[key]
        horizon_us = FORGET_AFTER * max(self.range_tau, self.bearing_tau) * 1e6
        stale = [ident for ident in book.states if t_us - book.last_seen_us[ident] > horizon_us]
        if stale:
            self._forget(s, store, stale)
            book = s.errors
        book.states[key] = len(s.x)
        new = self.subject_states(bearing_var)
        book.decaying = book.decaying + new
        store.append(s, np.array([variance for _, variance in new]))
        return book.states[key]

    def _forget(self, s: FilterState, store: Store, stale: list[Subject]) -> None:
        """The states of the ``stale`` subjects marginalized out, the others' indices closed up."""
        book, per, first = s.errors, self.per_subject, self.first
        dropped = [book.states[i] + k for i in stale for k in range(per)]
        store.drop(s, dropped)
        book.decaying = [d for i, d in enumerate(book.decaying) if first + i not in dropped]
        kept = sorted((index, ident) for ident, index in book.states.items() if ident not in stale)
        book.states = {ident: first + per * k for k, (_, ident) in enumerate(kept)}
        for ident in stale:
            del book.last_seen_us[ident]


@dataclass
class SlotBook:
    slot_of: dict[Subject, int] = field(default_factory=dict)  # subject -> index of its slot's first state
    last_seen_us: dict[Subject, int] = field(default_factory=dict)
    slot_vars: np.ndarray | None = None  # (slots x per subject,) stationary variances, read-only


class SlottedErrors(_SightingErrors):
    """The subjects' states in ``ERROR_SLOTS`` slots (module docstring). The state is [pose (4),
    wheel scales, slots, ...]: ``head_dim`` states before whatever follows (a SLAM map)."""

    def __init__(self, spec: SensorSpec, *, first_index: int) -> None:
        super().__init__(spec, first_index=first_index, range_scale_index=None)
        self.head_dim = first_index + ERROR_SLOTS * self.per_subject
        pairs = self.subject_states(spec.bearing_sigma_rad**2)
        # each slot state's tau and stationary variance; the bearing's is the datasheet's until a
        # subject takes the slot, then that of its sightings
        self.slot_taus = np.tile([pair[0] for pair in pairs], ERROR_SLOTS)
        self._initial_vars = np.tile([pair[1] for pair in pairs], ERROR_SLOTS)

    def start(self, s: FilterState) -> None:
        s.errors = SlotBook(slot_vars=frozen(self._initial_vars.copy()))

    def initialise(self, s: FilterState) -> None:
        """The scale and slot states appended after the pose (the slots with their current variances);
        no subject holds a slot."""
        s.x, s.P = added_states.append_states(s.x, s.P, np.array(self.scale_variances() + s.errors.slot_vars.tolist()))
        s.errors.slot_of, s.errors.last_seen_us = {}, {}

    def decaying(self, s: FilterState) -> tuple[int, np.ndarray, np.ndarray, int]:
        return self.first, self.slot_taus, s.errors.slot_vars, self.head_dim

    def stationary_variance(self, s: FilterState, index: int) -> float:
        return float(s.errors.slot_vars[index - self.first])

    def index_of(self, s: FilterState, store: Store, key: Subject, t_us: int, bearing_var: float) -> int:
        """The index of the slot (its first error state) of the sighted subject ``key``: its own slot
        if it has one, else a free slot or the slot of the subject seen longest ago, reset to 0 with
        the stationary variances (the bearing's a fraction of ``bearing_var``)."""
        book = s.errors
        book.last_seen_us[key] = t_us
        slot = book.slot_of.get(key)
        if slot is not None:
            return slot
        taken = set(book.slot_of.values())
        free = [i for i in range(self.first, self.head_dim, self.per_subject) if i not in taken]
        owners = dict(book.slot_of)
        if free:
            slot = free[0]
        else:
            oldest = min(owners, key=lambda ident: book.last_seen_us[ident])
            slot = owners.pop(oldest)
        states = list(range(slot, slot + self.per_subject))
        within = slice(slot - self.first, slot - self.first + self.per_subject)
        slot_vars = book.slot_vars.copy()
        slot_vars[within] = [variance for _, variance in self.subject_states(bearing_var)]
        book.slot_vars = frozen(slot_vars)
        s.x[states] = 0.0
        store.set_spread(s, states, book.slot_vars[within])
        book.slot_of = {**owners, key: slot}
        return slot

    def recovered(self, s: FilterState) -> None:
        """Slots are handed out afresh: the fallback's states are not theirs."""
        if s.x is not None:
            s.errors.slot_of = {}
