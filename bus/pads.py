"""Where a simulated swarm starts: its start pads on a square grid (the world places the vehicles
there; the ground station frames its views on them). Pure."""

from __future__ import annotations

import numpy as np


def start_pads(count: int, spacing_m: float) -> np.ndarray:
    """Pad centres on a square grid, ``spacing_m`` apart: (count, 2) in m."""
    side = int(np.ceil(np.sqrt(count)))
    index = np.arange(count)
    return np.stack([(index // side) * spacing_m, (index % side) * spacing_m], axis=1).astype(float)
