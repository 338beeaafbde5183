"""Two insiders, through real processes: vehicles 3 and 4 of 5 keep their positions honest and, from
5 s, accuse every honest vehicle in each of their validly signed V2V broadcasts (the ``accuse``
fault). Under the trust rule no honest vehicle distrusts another, and the honest vehicles that
range the accused contradict the accusations (``accusation_contradicted`` events, counted in
summary.json); the control, the rule before (a quorum of two believed accusers decides,
``vehicle.monitor.rule = "quorum-only"``), shows the honest vehicles distrusting each other, so the test can
fail. The first seconds: the same two accusing from the first second in a swarm told the default
f = 1 (two accusers are a quorum), before anyone has ranged anyone: no honest vehicle distrusts
another then either."""

import json

import pytest

from tests.integration.conftest import read_summary, run_swarm

pytestmark = pytest.mark.integration
INSIDERS, HONEST = (3, 4), (1, 2, 5)


def _scenario(tmp_path, name: str, rule: str) -> str:
    """``rule``: evidence (told f = 2), quorum-only (f = 1), or start (the defaults, accusing from 0 s)."""
    path = tmp_path / f"{name}.toml"
    f = 1 if rule == "quorum-only" else 2
    text = f'name = "{name}"\n[world]\nvehicles = 5\nseed = 11\n[clock]\nduration_s = 40\n'
    if rule != "start":
        text += f'[vehicle.monitor]\nrule = "{rule}"\nmax_compromised = {f}\n'
    start_s = 0.0 if rule == "start" else 5.0
    for v in INSIDERS:
        text += f'[[faults]]\nkind = "accuse"\nvehicle = {v}\nnames = {list(HONEST)}\nstart_s = {start_s}\n'
    path.write_text(text)
    return str(path)


def _events(run, kind: str) -> list[dict]:
    lines = (run / "events.jsonl").read_text().splitlines()
    return [e for e in map(json.loads, lines) if e["event"] == kind]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("insiders")
    out = {}
    for rule in ("evidence", "quorum-only", "start"):
        result = run_swarm(tmp, _scenario(tmp, rule, rule), "--name", rule)
        assert result.returncode == 0, result.stdout + result.stderr
        out[rule] = tmp / rule
    return out


def _honest_distrusting_honest(run) -> list[dict]:
    return [e for e in _events(run, "neighbour_distrusted") if e["vehicle"] in HONEST and e["neighbour"] in HONEST]


def test_no_honest_vehicle_distrusts_another_and_the_accusers_are_contradicted(runs):
    assert _honest_distrusting_honest(runs["evidence"]) == []
    contradicted = _events(runs["evidence"], "accusation_contradicted")
    assert {e["accuser"] for e in contradicted} == set(INSIDERS), contradicted  # nobody else accused anyone
    assert {e["accused"] for e in contradicted} <= set(HONEST)
    by_honest = {e["vehicle"] for e in contradicted if e["vehicle"] in HONEST}
    assert len(by_honest) >= 2, contradicted  # the insiders' own monitors, which run honestly, may judge too
    assert read_summary(runs["evidence"])["events"]["accusation_contradicted"] == len(contradicted)
    # said once per judge and accuser in 35 s of accusations at 5 Hz, not at every broadcast
    assert len(contradicted) <= 5 * len(INSIDERS), contradicted


def test_the_control_the_old_quorum_rule_turns_the_honest_vehicles_against_each_other(runs):
    turned = _honest_distrusting_honest(runs["quorum-only"])
    assert turned, "the old rule should let two insiders switch the honest swarm's cooperation off"
    assert all(e["reason"].startswith("accused by") for e in turned), turned


def test_in_the_first_seconds_no_honest_vehicle_distrusts_another_on_a_quorums_word(runs):
    assert _honest_distrusting_honest(runs["start"]) == []
    contradicted = _events(runs["start"], "accusation_contradicted")  # heard, and judged against evidence
    assert {e["accuser"] for e in contradicted if e["vehicle"] in HONEST} == set(INSIDERS), contradicted
