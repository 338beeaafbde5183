"""Unicycle kinematics at constant altitude (cooperative-localization paper, motion model)."""

from __future__ import annotations

import math

import numpy as np

SCALAR_ARCS = 16  # up to this many arcs (substeps x vehicles) in plain floats: numpy's per-call cost dominates


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap radians to [-pi, pi)."""
    return (np.asarray(angle) + np.pi) % (2.0 * np.pi) - np.pi


def chord_factor(half_turn: np.ndarray) -> np.ndarray:
    """sin(a) / a elementwise (1 at a = 0): the chord of an arc turning 2a over its length."""
    return np.divide(np.sin(half_turn), half_turn, out=np.ones_like(half_turn), where=half_turn != 0.0)


def unicycle_arcs(pose: np.ndarray, speed_mps: np.ndarray, yaw_rate_radps: np.ndarray, dt_s: float) -> np.ndarray:
    """Exact arc integration of ``[x, y, theta]`` (x north, y east, theta from north towards east; m,
    m, rad) over S arcs in a row, each with its inputs held over ``dt_s``: pose (N, 3), speed_mps and
    yaw_rate_radps (S, N). Each arc moves by its chord, speed dt sin(a) / a with a half its turn,
    along the heading at its middle; the heading is wrapped once, at the end. Returns (N, 3)."""
    if speed_mps.size <= SCALAR_ARCS:
        return _arcs_in_floats(pose, speed_mps, yaw_rate_radps, dt_s)
    turn = yaw_rate_radps * dt_s  # (S, N)
    half = 0.5 * turn
    chord = speed_mps * dt_s * chord_factor(half)
    out = np.empty_like(pose)
    if len(turn) == 1:  # one arc (the common case): no running sums
        mid = pose[:, 2] + half[0]
        out[:, 0] = pose[:, 0] + chord[0] * np.cos(mid)
        out[:, 1] = pose[:, 1] + chord[0] * np.sin(mid)
        out[:, 2] = wrap_angle(pose[:, 2] + turn[0])
        return out
    end = pose[:, 2] + turn.cumsum(axis=0)  # heading at each arc's end
    mid = end - half
    out[:, 0] = pose[:, 0] + (chord * np.cos(mid)).sum(axis=0)
    out[:, 1] = pose[:, 1] + (chord * np.sin(mid)).sum(axis=0)
    out[:, 2] = wrap_angle(end[-1])
    return out


def _arcs_in_floats(pose: np.ndarray, speed_mps: np.ndarray, yaw_rate_radps: np.ndarray, dt_s: float) -> np.ndarray:
    """:func:`unicycle_arcs` for a few arcs, one float at a time (same arithmetic, same shapes)."""
    out = np.empty_like(pose)
    speeds, rates = speed_mps.T.tolist(), yaw_rate_radps.T.tolist()  # (N, S)
    for n, (x, y, heading) in enumerate(pose.tolist()):
        for speed, rate in zip(speeds[n], rates[n]):
            half = 0.5 * rate * dt_s
            chord = speed * dt_s * (math.sin(half) / half if half != 0.0 else 1.0)
            mid = heading + half
            x += chord * math.cos(mid)
            y += chord * math.sin(mid)
            heading += rate * dt_s
        out[n] = (x, y, (heading + math.pi) % (2.0 * math.pi) - math.pi)
    return out
