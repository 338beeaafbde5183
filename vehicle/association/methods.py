"""The association methods by their configuration names (``vehicle.association``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from vehicle.association.ant_colony import ant_colony
from vehicle.association.jcbb import jcbb
from vehicle.association.nearest import nearest_neighbour
from vehicle.association.optimum import optimal_assignment
from vehicle.association.problem import Problem

Method = Callable[[Problem, np.random.Generator], np.ndarray]

METHODS: dict[str, Method] = {
    "nn": lambda p, rng: nearest_neighbour(p),
    "jcbb": lambda p, rng: jcbb(p),
    "aco": ant_colony,
    "optimum": lambda p, rng: optimal_assignment(p),
}
