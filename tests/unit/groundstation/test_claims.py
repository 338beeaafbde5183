"""Vehicle ids claimed from the ground station: unique, the same again after a restart (with the
restart counted), refused when the swarm is full, kept across a ground-station restart."""

from bus.claims import ClaimRequest
from groundstation.claims import IdRegister


def test_claims_are_unique_stable_across_restarts_and_bounded(tmp_path):
    register = IdRegister(vehicles=3, path=tmp_path / "claims.json")
    replies = [register.claim(ClaimRequest(host=h)) for h in ("c1", "c2", "c3")]
    assert [(r.vehicle_id, r.restarts) for r in replies] == [(1, 0), (2, 0), (3, 0)]
    again = register.claim(ClaimRequest(host="c2"))
    assert (again.vehicle_id, again.restarts) == (2, 1)
    full = register.claim(ClaimRequest(host="c4"))
    assert not full.ok and "full" in full.error
    reloaded = IdRegister(vehicles=3, path=tmp_path / "claims.json")
    assert reloaded.claim(ClaimRequest(host="c3")).restarts == 1
