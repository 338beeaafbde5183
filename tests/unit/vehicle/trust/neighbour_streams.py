"""Synthetic fix streams for the neighbour monitor's tests: innovations N(0, S) (0.5 m on each axis)
plus an offset, at the ranging rate, next to a consistent witness (the observer's grounds to trust
itself)."""

from vehicle.models.kalman import UpdateResult
from vehicle.trust.neighbour_fixes import fix_of
from vehicle.trust.neighbours import MonitorSpec, see

SPEC = MonitorSpec()
PERIOD_US = 200_000  # ranging at 5 Hz
S = (0.25, 0.0, 0.25)  # innovation covariance of every fix (0.5 m sigma on each axis)
WITNESS = 9  # a consistent neighbour


def fix(t_us: int, y: tuple[float, float], gate: float = 13.8):
    nis = (y[0] ** 2 + y[1] ** 2) / 0.25
    return fix_of(t_us, UpdateResult(nis <= gate, nis, nis / gate, y, S))


def witness(book, rng, t_us, spec: MonitorSpec = SPEC):
    y = rng.normal(0.0, 0.5, 2)
    assert see(book, spec, WITNESS, fix(t_us, (float(y[0]), float(y[1])))) is None


def stream(book, neighbour, offsets, rng, start_us=0, spec: MonitorSpec = SPEC, between=None):
    """Fixes of ``neighbour`` with innovation noise N(0, S) plus ``offsets`` (k, 2), next to a
    consistent witness; the verdicts about ``neighbour``. ``between(t_us)`` runs before each fix."""
    verdicts = []
    for k, offset in enumerate(offsets):
        t = start_us + k * PERIOD_US
        witness(book, rng, t, spec)
        if between is not None:
            between(t)
        y = rng.normal(0.0, 0.5, 2) + offset
        verdict = see(book, spec, neighbour, fix(t, (float(y[0]), float(y[1]))))
        if verdict is not None:
            verdicts.append(verdict)
    return verdicts
