"""Inputs integrated between propagations, so a filter predicts once per loop cycle (pure).

A sampled input (odometry speed, gyro rate) is held from one sample to the next (zero-order hold).
Over a propagation interval [t0, t1] the filter needs its mean, sum(v_i o_i) / dt, where o_i is
how long sample i was held inside the interval, and the variance of that mean for a sample noise
sigma (independent between samples): sigma^2 sum(o_i h_i) / dt^2, h_i the whole hold of sample i.
A sample held across a propagation boundary carries one error into both intervals: its pieces o
and h - o add sigma^2 h^2 in total, as the one error held for h does (sum(o_i^2) would count only
o^2 + (h - o)^2, as little as half, and make a filter cycling at a rate that does not divide the
input's overconfident). A hold still open at the close counts the longer of the time since its
sample and the previous hold. One sample held over the whole interval gives sigma^2, n evenly
spread samples sigma^2 / n.

Past the time its next sample was due (``period_us`` after its stamp), a held input is extrapolated:
the next sample is late, lost or never sent, and the vehicle's true speed or turn rate may have
changed meanwhile. That change is modelled as a random walk from the due time (the vehicle's
manoeuvres, a datasheet rate in units per sqrt(s)); :meth:`HeldInput.walk_s` gives what it adds to
the variance of the interval's mean, so that a filter cycling on inputs that have not come yet
claims no more than it knows (docs/decisions/realtime-restart.md).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass
class HeldInput:
    """One input's hold since the last propagation at ``start_us``."""

    value: float | None = None
    stamp_us: int | None = None  # time of the latest sample
    start_us: int = 0  # time of the last close (propagation)
    _segment_us: int = 0  # start of the current hold inside the interval
    _integral: float = 0.0  # value x us
    _sq_us2: float = 0.0  # sum of o_i h_i of closed segments (us^2): see the module docstring
    _last_hold_us: int = 0  # the previous sample's whole hold
    segments: list = None  # (duration us, value) of the closed holds of the last interval
    period_us: int = 0  # the next sample is due this long after the latest (0: never extrapolated)

    def __post_init__(self) -> None:
        self.segments, self._open, self._weight = [], [], 1.0

    def sample(self, stamp_us: int, value: float, weight: float = 1.0) -> None:
        """A new sample at ``stamp_us`` (>= the last close); it is held from now on. ``weight``: its
        variance relative to the nominal sigma^2 (a measurement that reports its own variance)."""
        if self.value is not None:
            held = stamp_us - self._segment_us
            self._last_hold_us = stamp_us - self.stamp_us
            self._integral += self.value * held
            self._sq_us2 += float(held) * self._last_hold_us * self._weight
            if held > 0:
                self._open.append((held, self.value))
        self._segment_us = max(stamp_us, self.start_us)
        self.value, self.stamp_us, self._weight = value, stamp_us, weight

    def close(self, t_us: int) -> tuple[float, float]:
        """Mean over [start, t_us] and the variance factor sum(o_i^2) / dt^2 (multiply by sigma^2);
        ``segments`` then holds the interval's holds in order. A new interval starts at ``t_us``.
        Without any sample: (0.0, 1.0) and one zero segment."""
        dt = t_us - self.start_us
        if self.value is None or dt <= 0:
            self.segments = [(dt, 0.0)] if dt > 0 else []
            self.restart(t_us)
            return 0.0, 1.0
        held = t_us - self._segment_us
        integral = self._integral + self.value * held
        sq = self._sq_us2 + float(held) * max(t_us - self.stamp_us, self._last_hold_us) * self._weight
        self.segments = self._open + ([(held, self.value)] if held > 0 else [])
        self.restart(t_us)
        return integral / dt, sq / (float(dt) * dt)

    def walk_s(self, t_us: int) -> float:
        """What a unit random walk of the input (1 unit/sqrt(s)) from the time its next sample was due
        adds to the variance of its mean over [start, ``t_us``] (s; multiply by the walk's rate squared):
        0 while the latest sample is not overdue. Call it before :meth:`close`."""
        if self.stamp_us is None or not self.period_us:
            return 0.0
        return walk_variance_s(self.start_us, t_us, self.stamp_us + self.period_us)

    def copy(self) -> HeldInput:
        """An independent copy (for the fusion horizon's checkpoints)."""
        twin = HeldInput(
            self.value,
            self.stamp_us,
            self.start_us,
            self._segment_us,
            self._integral,
            self._sq_us2,
            self._last_hold_us,
            None,
            self.period_us,
        )
        twin.segments, twin._open, twin._weight = list(self.segments), list(self._open), self._weight
        return twin

    def restart(self, t_us: int) -> None:
        """Forget the interval so far (the filter was re-initialised at ``t_us``); keep the held value."""
        self.start_us = self._segment_us = t_us
        self._integral, self._sq_us2, self._open = 0.0, 0.0, []


def walk_variance_s(start_us: int, t_us: int, due_us: int) -> float:
    """Variance (s, per unit walk rate squared) of the mean over [start, t] of a Wiener process W that
    is 0 until ``due_us`` and walks from then on: with a = how long it has walked at the interval's
    first overdue instant and L the overdue part of the interval, (1/dt^2) Var(integral of W) =
    (a^2 L + a L^2 + L^3 / 3) / dt^2. Summed over consecutive intervals, each weighted by dt^2, this is
    exactly the variance of the integral over all of them, L^3 / 3 from the due time on."""
    first = max(start_us, due_us)
    if t_us <= first:
        return 0.0
    a, length, dt = (first - due_us) * 1e-6, (t_us - first) * 1e-6, (t_us - start_us) * 1e-6
    return (a * a * length + a * length * length + length**3 / 3.0) / (dt * dt)


def swept(segments: list[tuple[int, float]]) -> float:
    """sum |value| * duration over an input's hold segments [(duration us, value)]: the distance (m) or
    the angle (rad) that a speed or a rate moved the vehicle by over them."""
    return sum(abs(value) * held_us for held_us, value in segments) * 1e-6
