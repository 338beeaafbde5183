"""A seeded random fault timeline with every kind of fault, for chaos runs (`swarm up --chaos SEED`).

Each kind of the registry (bus.faults.KINDS) appears at least once (where the swarm is large enough
for it: ``chaos_min_vehicles``), with the parameters its own ``chaos`` entry draws; faults start
between 10% and 70% of the run and end by 95% of it (a kill's restart comes 3-15 s after it), so every
fault starts and ends while the swarm runs. Zones are placed over the square of start pads
(``spacing_m`` apart on ceil(sqrt(N)) columns).
"""

from __future__ import annotations

import math

import numpy as np

from bus.faults import BY_KIND, ChaosSwarm


def chaos_faults(seed: int, *, vehicles: int, duration_s: float, spacing_m: float, extra: int = 6) -> list[dict]:
    """Every kind once plus ``extra`` random ones, each with a start and duration inside the run."""
    rng = np.random.default_rng([seed, 0xC4A05])
    possible = [name for name, kind in BY_KIND.items() if vehicles >= kind.chaos_min_vehicles]
    kinds = possible + [str(k) for k in rng.choice([k for k in possible if BY_KIND[k].chaos_extra], extra)]
    swarm = ChaosSwarm(vehicles, (math.ceil(math.sqrt(vehicles)) - 1) * spacing_m + 1.0)
    faults = []
    for n, name in enumerate(kinds, start=1):
        kind = BY_KIND[name]
        fault = {"kind": name, "name": f"chaos-{n}-{name}", **kind.chaos(rng, swarm)}
        start = float(rng.uniform(0.1, 0.7))
        fault["start_s"] = round(start * duration_s, 2)
        if kind.chaos_lasts:  # every fault ends inside the run (by 95% of it)
            fault["for_s"] = round(float(rng.uniform(0.05, min(0.25, 0.95 - start))) * duration_s, 2)
        faults.append(fault)
    return faults
