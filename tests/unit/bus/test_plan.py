"""The fault plan and `swarm fault` requests as they cross the bus: round trips, validation with one
clear error, and fuzzing of the decoders (nothing but DecodeError ever escapes)."""

import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus.errors import DecodeError
from bus.faults import Delay, JamGnss, Kill, Loss, check_fault
from bus.plan import FaultPlan, FaultReply, FaultRequest, decode_json, encode_json

PLAN = FaultPlan(
    version=3,
    faults=(
        Delay(name="d", dst="v*", topic="mavlink", delay_s=0.2, jitter_s=0.05, distribution="pareto"),
        Loss(name="l", dst="v3", percent=30, burst=4),
        JamGnss(name="j", center_m=(40.0, 10.0), radius_m=25.0, start_s=5, for_s=60),
        Kill(name="k", vehicle=2, start_s=10, restart_after_s=10),
    ),
)


def test_plan_round_trip():
    assert decode_json(FaultPlan, encode_json(PLAN)) == PLAN


@pytest.mark.parametrize(
    "payload, message",
    [
        (b"{", "FaultPlan"),
        (b'{"version": -1, "faults": []}', "version"),
        (b'{"version": 1, "faults": [{"kind": "teleport"}]}', "faults"),
        (b'{"version": 1, "faults": [{"kind": "loss", "percent": 130}]}', "percent"),
        (b'{"version": 1, "faults": [{"kind": "delay", "delay_s": -1}]}', "delay_s"),
        (b'{"version": 1, "faults": [], "extra": 1}', "extra"),
    ],
)
def test_malformed_plans_raise_one_clear_error(payload, message):
    with pytest.raises(DecodeError, match=message):
        decode_json(FaultPlan, payload)


def test_faults_naming_vehicles_or_endpoints_outside_the_swarm_are_refused():
    with pytest.raises(ValueError, match="v9"):
        check_fault(Loss(dst="v9", percent=1), vehicles=3)
    with pytest.raises(ValueError, match="vehicle 4 does not exist"):
        check_fault(Kill(vehicle=4), vehicles=3)
    with pytest.raises(ValueError, match="topic"):
        check_fault(Loss(topic="video", percent=1), vehicles=3)
    check_fault(Loss(dst="v[1-3]", src="gs", percent=1), vehicles=3)


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-(2**70), 2**70) | st.floats() | st.text(max_size=10),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=10), children, max_size=5),
    max_leaves=20,
)
FIELDS = [
    "kind",
    "name",
    "start_s",
    "for_s",
    "dst",
    "src",
    "topic",
    "delay_s",
    "jitter_s",
    "distribution",
    "percent",
    "burst",
    "center_m",
    "radius_m",
    "vehicle",
    "sensor",
    "restart_after_s",
    "gap_s",
]


@given(st.binary(max_size=300))
def test_garbage_bytes_raise_decode_error_only(payload):
    for cls in (FaultPlan, FaultRequest, FaultReply):
        try:
            decode_json(cls, payload)
        except DecodeError:
            pass


@given(st.dictionaries(st.sampled_from(FIELDS), json_values, max_size=8), st.sampled_from(["add", "remove", "x"]))
def test_json_requests_with_arbitrary_fault_fields_decode_or_raise_decode_error(fault, op):
    payload = json.dumps({"op": op, "fault": fault}, default=str).encode()
    try:
        request = decode_json(FaultRequest, payload)
    except DecodeError:
        return
    assert request.op == op


@given(st.data())
def test_mutated_plans_decode_or_raise_decode_error(data):
    payload = bytearray(encode_json(PLAN))
    for _ in range(data.draw(st.integers(1, 4))):
        payload[data.draw(st.integers(0, len(payload) - 1))] = data.draw(st.integers(0, 255))
    try:
        decode_json(FaultPlan, bytes(payload))
    except DecodeError:
        pass


@given(st.binary(max_size=200) | st.builds(lambda h: json.dumps({"host": h}).encode(), st.text(max_size=140)))
def test_claim_decoders_raise_decode_error_only(payload):
    from bus.claims import ClaimReply, ClaimRequest

    for cls in (ClaimRequest, ClaimReply):
        try:
            decode_json(cls, payload)
        except DecodeError:
            pass
