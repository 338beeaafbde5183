"""Verdicts shared over the V2V broadcasts, in a swarm of the honest world: the real vehicle nodes and
the world in one process over the in-memory bus, in lockstep (experiments.harness.swarm_in_memory),
as ``swarm experiment liar``'s gross profile flies them (seed 4, 25 s). Vehicle 5 ranges the liar
until the lie begins (10.0 s) and then not before 29.6 s, so it has no evidence of its own; the
vehicles that do range it distrust it within 2 s of the lie and say so in their broadcasts, and
vehicle 5, ranging them, distrusts the liar on their word. Without the shared verdicts it could
not: it has no failing fix of the liar to judge."""

import pytest

from bus.config import build_config
from experiments.harness import swarm_in_memory
from experiments.liar import LIAR, LIE_START_S, Case, liar_config
from vehicle.trust.neighbours import NeighbourRecord

pytestmark = pytest.mark.monte_carlo
SEED, DURATION_S, UNINFORMED = 4, 25.0, 5


@pytest.fixture(scope="module")
def books():
    config = liar_config(Case("gross", True, SEED)).model_dump(mode="json")
    config["clock"]["duration_s"] = DURATION_S
    config["vehicle"]["monitor"]["max_compromised"] = 1
    nodes: list = []
    swarm_in_memory(build_config(config), nodes_out=nodes)
    return {node.vehicle_id: node.estimator.state.neighbours for node in nodes}


def test_a_vehicle_with_no_evidence_of_its_own_distrusts_the_liar_on_the_word_of_those_with_some(books):
    record = books[UNINFORMED].records[LIAR]
    assert record.fixes and all(f.stamp_us <= LIE_START_S * 1e6 + 200_000 for f in record.fixes)
    assert not record.distrusted  # no verdict of its own: it ranged the liar only until the lie began ...
    assert record.hearsay.startswith("accused by "), record  # ... but a quorum's word
    accusers = [int(v) for v in record.hearsay.removeprefix("accused by ").replace("v", "").split(", ")]
    assert len(accusers) >= 2 and LIAR not in accusers, record.hearsay
    assert all(LIAR in books[j].accused() for j in accusers)  # each said what it found itself
    assert not books[UNINFORMED].trusts(LIAR)


def test_every_vehicle_that_ranged_the_liar_distrusts_it_and_nobody_accuses_an_honest_vehicle(books):
    honest = {v: book for v, book in books.items() if v != LIAR}
    lie_us = LIE_START_S * 1e6 + 200_000
    ranged = [
        v
        for v, book in honest.items()
        if any(f.stamp_us > lie_us for f in book.records.get(LIAR, NeighbourRecord()).fixes)
    ]
    assert len(ranged) >= 2 and all(not honest[v].trusts(LIAR) for v in ranged), ranged
    assert all(set(book.accused()) <= {LIAR} for book in honest.values())
    on_their_own = [v for v, book in honest.items() if book.accused() == (LIAR,)]
    assert len(on_their_own) >= 2, on_their_own  # the quorum came from evidence, not from each other
