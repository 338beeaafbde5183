"""A vehicle whose own GNSS is spoofed, in a swarm of the honest world: the real vehicle nodes and the
world in one process over the in-memory bus, in lockstep (experiments.harness.swarm_in_memory), as
``swarm experiment liar``'s spoofed profile flies them. Its GNSS monitor flags the spoofer, then finds
the spoofed fixes agreeing with each other; a reset to them is refused because the neighbours that
range it speak against the jump, so it stays where they see it and its broadcasts stay true. The
control (the neighbour monitor off, and with it the neighbours' say) follows the spoofer and pulls
the honest vehicles with it, so the test can fail."""

import numpy as np
import pytest

from bus.config import build_config
from experiments.harness import swarm_in_memory
from experiments.liar import LIAR, LIE_START_S, Case, liar_config

pytestmark = pytest.mark.monte_carlo
SEED = 3


def _rmse_from_lie(run: dict[str, np.ndarray]) -> float:
    after = run["t_s"] >= LIE_START_S
    return float(np.sqrt(np.mean(run["error_m"][after] ** 2)))


@pytest.fixture(scope="module")
def runs():
    return {
        defence: {
            vid: _rmse_from_lie(run)
            for vid, run in swarm_in_memory(build_config(liar_config(Case("spoofed", defence, SEED)))).items()
        }
        for defence in (True, False)
    }


def test_the_spoofed_vehicle_is_held_where_its_neighbours_see_it(runs):
    held, followed = runs[True][LIAR], runs[False][LIAR]
    assert followed > 4.0, runs[False]  # the control: it follows the 0.5 m/s spoofer
    assert held < 1.0, runs[True]  # GNSS-class: the honest world's receivers wander about 0.9 m


def test_the_honest_vehicles_are_not_pulled(runs):
    honest = {d: np.sqrt(np.mean([r**2 for vid, r in rmse.items() if vid != LIAR])) for d, rmse in runs.items()}
    assert honest[False] > 1.5 * honest[True], honest
