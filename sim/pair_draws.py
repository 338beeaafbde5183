"""Ranging draws per pair for a large swarm: the noise of vehicle i's ranging to vehicle j in one block
of steps comes from a counter-based generator keyed by (the block's key, j), made on first use, so
that a vehicle costs only the peers it ranges (a handful) instead of every vehicle of the swarm, and
faults and distances still never shift any stream (the block's key is one draw of the vehicle's
ranging generator per block, whatever is used)."""

from __future__ import annotations

import numpy as np

from sim.true_errors import student_scale

PAIRWISE_FROM = 65  # swarms of more vehicles draw per pair; smaller ones keep their (steps, N) blocks


class PairDraws:
    """One vehicle's ranging draws of one block, per peer on first use: white noise [range m, bearing
    rad] (steps, 2) at ``sigmas`` and heavy-tail factors (steps,) of ``dof`` (sim.true_errors)."""

    def __init__(self, key: int, steps: int, sigmas: np.ndarray, scale: float, dof: float) -> None:
        self.key, self.steps, self.sigmas, self.scale, self.dof = key, steps, sigmas, scale, dof
        self._pairs: dict[int, tuple[np.ndarray, np.ndarray]] = {}

    def of(self, peer: int) -> tuple[np.ndarray, np.ndarray]:
        """(noise (steps, 2), tail factors (steps,)) of the pair with ``peer`` (its 0-based index)."""
        if peer not in self._pairs:
            rng = np.random.Generator(np.random.Philox(key=[self.key, peer]))
            noise = rng.normal(0.0, self.sigmas, (self.steps, 2)) * self.scale
            self._pairs[peer] = (noise, student_scale(self.dof, rng, (self.steps,)))
        return self._pairs[peer]

    def noise(self) -> _Field:
        """The white noise, indexed ``[k, j]`` as a (steps, N, 2) block is."""
        return _Field(self, 0)

    def tail(self) -> _Field:
        """The heavy-tail factors, indexed ``[k, j]`` as a (steps, N) block is."""
        return _Field(self, 1)


class _Field:
    """``[k, j]`` indexing of one of a PairDraws' arrays, as the (steps, N, ...) blocks are indexed."""

    def __init__(self, draws: PairDraws, which: int) -> None:
        self.draws, self.which = draws, which

    def __getitem__(self, index: tuple[int, int]) -> np.ndarray:
        k, j = index
        return self.draws.of(int(j))[self.which][k]
