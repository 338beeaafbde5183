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


def test_a_claim_carries_the_vehicles_own_secrets_and_an_alive_id_is_never_handed_out_twice(tmp_path):
    from bus.secrets import vehicle_password, vehicle_signing_key

    master = bytes(range(32))
    register = IdRegister(vehicles=2, path=tmp_path / "claims.json", master_key=master)
    first = register.claim(ClaimRequest(host="alpha"))
    assert first.ok and first.signing_key == vehicle_signing_key(master, first.vehicle_id).hex()
    assert first.zenoh_password == vehicle_password(master, first.vehicle_id)
    refused = register.claim(ClaimRequest(host="alpha"), alive={first.vehicle_id})  # a second "alpha" while it lives
    assert not refused.ok and "alive" in refused.error and not refused.signing_key
    again = register.claim(ClaimRequest(host="alpha"), alive=set())  # after it died: a restart
    assert again.ok and again.vehicle_id == first.vehicle_id and again.restarts == 1
