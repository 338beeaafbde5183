"""Sensor message codec: round trips, and strict rejection of anything malformed."""

import math

import msgpack
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from bus import messages as m
from bus.errors import DecodeError

SAMPLES = [
    m.ImuSample(1, 10, 0, np.array([0.1, -0.2, 0.3]), np.array([0.0, 1.0, -9.8])),
    m.WheelOdometry(2, 20, 1, 3.5, -0.1),
    m.GnssFix(3, 30, 2, np.array([10.0, -5.0]), np.array([[2.25, 0.1], [0.1, 2.25]])),
    m.PosePrior(4, 0, 0, np.array([1.0, 2.0, 0.5]), np.diag([0.25, 0.25, 0.01])),
    m.Truth(5, 40, 3, np.array([1.0, 2.0, -3.0]), 4.0, 0.2),
    m.ClockTick(7, 140_000, 1_700_000_000_000_000_000, False),
    m.ClockTick(8, 160_000, 1_700_000_000_000_000_000, True, (1, 16, 8, 0, 1, 16, 8, 1)),
    m.ClockTick(9, 180_000, 1_700_000_000_000_000_000, False, (1, 16, 8, 0, 2), (1, 3), (1,)),
    m.RangeBearing(2, 200_000, 4, 3, 42.5, -0.3, np.diag([0.09, 0.0004])),
    m.TickAck(9, 7),
    m.VehicleStatus(1, 100, 5, 0, 12.5, 300.0, 0, 1, 0, 0, 3, 4, 5, 6, 7),
    m.VehicleStatus(1, 100, 5, 0, 12.5, 300.0, 0, 1, 0, 0, 3, 4, 5, 6, 7, nis=tuple(float(k) for k in range(16))),
    m.VehicleStatus(1, 100, 5, 0, 12.5, 300.0, 0, 1, 0, 0, 3, v2v_received=42),
    m.RunEnd(3001, 60_000_000, 5),
]


def _equal(a, b) -> bool:
    return all(
        np.array_equal(getattr(a, f), getattr(b, f))
        if isinstance(getattr(a, f), np.ndarray)
        else getattr(a, f) == getattr(b, f)
        for f in a.__dataclass_fields__
    )


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda msg: type(msg).__name__)
def test_round_trip(msg):
    assert _equal(m.decode(type(msg), m.encode(msg)), msg)


def _body(msg) -> dict:
    return msgpack.unpackb(m.encode(msg), raw=False)


def _pack(body: dict) -> bytes:
    return msgpack.packb(body, use_bin_type=True)


@pytest.mark.parametrize(
    "mutate, reason",
    [
        (lambda b: b.update(vehicle_id=0), "outside"),
        (lambda b: b.update(vehicle_id=True), "integer"),
        (lambda b: b.update(stamp_us=-1), "outside"),
        (lambda b: b.pop("seq"), "missing"),
        (lambda b: b.update(extra=1), "unexpected"),
        (lambda b: b.update(type="ImuSample"), "type tag"),
        (lambda b: b.update(v=99), "version"),
        (lambda b: b["position_m"].update(data=np.array([math.nan, 0.0]).tobytes()), "finite"),
        (lambda b: b["position_m"].update(data=np.array([math.inf, 0.0]).tobytes()), "finite"),
        (lambda b: b["position_m"].update(shape=[3]), "shape"),
        (lambda b: b["position_m"].update(dtype="<f4"), "dtype"),
        (lambda b: b["position_m"].update(data=b"\x00" * 15), "raw bytes"),
        (lambda b: b["covariance_m2"].update(data=np.array([1.0, 0.0, 0.0, -1.0]).tobytes()), "positive definite"),
        (lambda b: b["covariance_m2"].update(data=np.array([1.0, 0.5, 0.0, 1.0]).tobytes()), "symmetric"),
        (lambda b: b["position_m"].update(data=np.array([1e9, 0.0]).tobytes()), "within"),
    ],
)
def test_malformed_gnss_is_rejected_with_a_clear_error(mutate, reason):
    body = _body(SAMPLES[2])
    mutate(body)
    with pytest.raises(DecodeError, match=reason):
        m.decode(m.GnssFix, _pack(body))


def test_payload_of_another_type_is_rejected():
    with pytest.raises(DecodeError, match="type tag"):
        m.decode(m.GnssFix, m.encode(SAMPLES[0]))


@given(st.binary(max_size=400))
def test_garbage_bytes_raise_decode_error_only(payload):
    for cls in (m.ImuSample, m.GnssFix, m.ClockTick, m.RangeBearing, m.VehicleStatus):
        try:
            m.decode(cls, payload)
        except DecodeError:
            pass


@given(st.sampled_from(SAMPLES), st.data())
def test_mutated_valid_payloads_decode_or_raise_decode_error(msg, data):
    payload = bytearray(m.encode(msg))
    for _ in range(data.draw(st.integers(1, 4))):
        index = data.draw(st.integers(0, len(payload) - 1))
        payload[index] = data.draw(st.integers(0, 255))
    try:
        decoded = m.decode(type(msg), bytes(payload))
    except DecodeError:
        return
    assert type(decoded) is type(msg)


json_like = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**63), 2**64 - 1)
    | st.floats()
    | st.text(max_size=8)
    | st.binary(max_size=16),
    lambda children: st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=8), children, max_size=4),
    max_leaves=12,
)


@given(st.sampled_from(SAMPLES), st.text(max_size=15), json_like)
def test_well_formed_msgpack_with_wrong_values_raises_decode_error(msg, field, value):
    body = _body(msg)
    body[field if field else next(iter(body))] = value
    try:
        m.decode(type(msg), _pack(body))
    except DecodeError:
        pass


@pytest.mark.parametrize(
    "field, value",
    [
        ("v2v_published", [1, True, 3]),
        ("v2v_published", [1, -1]),
        ("v2v_published", [2**53 + 1]),
        ("v2v_published", [1, 2.0]),
        ("v2v_published", ["1"]),
        ("v2v_published", [1, None]),
        ("members", [1, 251]),
        ("running", [[1]]),
    ],
)
def test_a_tick_list_that_is_not_one_of_counts_is_refused_by_name(field, value):
    """The clock's lists (a count per vehicle, vehicle ids): plain integers in range, nothing else."""
    body = _body(m.ClockTick(9, 180_000, 1, False, (1, 2, 3), (1, 3), (1,)))
    body[field] = value
    with pytest.raises(DecodeError, match=f"ClockTick.{field}: entries must be integers"):
        m.decode(m.ClockTick, _pack(body))


@pytest.mark.parametrize(
    "nis, why",
    [
        ([1.0] * 15, "list of 0 or 16 numbers"),
        ([float("nan")] + [0.0] * 15, "finite numbers"),
        ([True] + [0.0] * 15, "finite numbers"),
        (["1"] + [0.0] * 15, "finite numbers"),
        ([1e16] + [0.0] * 15, "finite numbers"),
        ("not a list", "list of 0 or 16 numbers"),
    ],
)
def test_a_status_nis_book_that_is_not_one_is_refused_by_name(nis, why):
    body = _body(m.VehicleStatus(1, 100, 5, 0, 12.5, 300.0, 0, 1, 0, 0, 3))
    body["nis"] = nis
    with pytest.raises(DecodeError, match=f"VehicleStatus.nis: .*{why}"):
        m.decode(m.VehicleStatus, _pack(body))


@given(
    st.lists(st.one_of(st.floats(), st.integers(-(2**63), 2**64 - 1), st.booleans(), st.text(max_size=3)), max_size=20)
)
def test_any_status_nis_list_decodes_or_raises_decode_error(values):
    body = _body(m.VehicleStatus(1, 100, 5, 0, 12.5, 300.0, 0, 1, 0, 0, 3))
    body["nis"] = values
    try:
        decoded = m.decode(m.VehicleStatus, _pack(body))
    except DecodeError:
        return
    assert len(decoded.nis) in (0, 16) and all(abs(v) <= 1e15 for v in decoded.nis)
