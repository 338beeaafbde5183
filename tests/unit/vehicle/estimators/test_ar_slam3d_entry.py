"""Which unpaired points enter the 3-D map (vehicle.estimators.ar_slam3d_entry): the paper's rule takes
every point within R at once; the default makes it a candidate and lets it enter on its second
sighting, by id or by the gate, and lets a candidate go when it is not seen again."""

import numpy as np

from vehicle.estimators.ar_slam3d_entry import CANDIDATE_FRAMES, Unpaired, entering


def _points(xyz, within, ident=None) -> Unpaired:
    xyz = np.asarray(xyz, float)
    identified = ident is not None
    return Unpaired(
        index=np.arange(len(xyz)) + 10,
        xyz=xyz,
        cov=np.tile(np.eye(3) * 0.01, (len(xyz), 1, 1)),
        ident=np.asarray(ident if identified else [-1] * len(xyz)),
        identified=identified,
        within=np.asarray(within),
    )


def test_the_papers_rule_takes_every_point_within_the_range_at_once():
    points = _points([[0, 0, 10], [0, 0, 40]], [True, False], ident=[7, 8])
    enter, candidates = entering([], points, 1, 16.3, "first")
    assert enter == {10: 7} and candidates == []


def test_a_point_enters_on_its_second_sighting_by_id_or_by_the_gate_and_a_candidate_not_seen_again_goes():
    for ident in ([7, 8], None):
        first = _points([[0, 0, 10], [5, 0, 10]], [True, True], ident=ident)
        enter, candidates = entering([], first, 1, 16.3, "second")
        assert enter == {} and len(candidates) == 2
        again = _points([[0.05, 0, 10]], [False], ident=None if ident is None else [7])  # beyond R now: still enters
        enter, candidates = entering(candidates, again, 2, 16.3, "second")
        assert enter == {10: -1 if ident is None else 7} and len(candidates) == 1
        _, candidates = entering(candidates, _points(np.zeros((0, 3)), []), 1 + CANDIDATE_FRAMES, 16.3, "second")
        assert candidates == []  # not seen again within CANDIDATE_FRAMES frames
