"""What a vehicle says that the ground station makes an event of (bus.notices): written and read by
one module, read totally from any text."""

from hypothesis import given
from hypothesis import strategies as st

from bus import notices
from bus.notices import Contradicted, EstimatorReset, Verdict, read, text_of
from groundstation.vehicle_says import announced

SAID = [
    EstimatorReset("non-finite or indefinite covariance"),
    Verdict(3, False, "8 of 8 fixes fail the gate"),
    Verdict(12, True, "consistent again"),
    Contradicted(4, 1),
]


def test_what_a_vehicle_writes_the_ground_station_reads_back():
    for said in SAID:
        assert read(text_of(said)) == said
    # cut to the wire's 50 characters, a reset is still a reset
    assert read(text_of(SAID[0])[: notices.MAX_TEXT]) == EstimatorReset("non-finite or indefinite covarian")


def test_each_notice_is_one_event_naming_what_it_says():
    assert announced(text_of(SAID[1])) == [
        ("neighbour_distrusted", {"neighbour": 3, "reason": "8 of 8 fixes fail the gate"})
    ]
    assert announced(text_of(SAID[2]))[0][0] == "neighbour_trusted"
    assert announced(text_of(SAID[3])) == [("accusation_contradicted", {"accuser": 4, "accused": 1})]
    assert announced(text_of(SAID[0])) == [("estimator_reset", {"text": text_of(SAID[0])})]


def test_plain_messages_and_impossible_ids_are_no_notice():
    assert read("GNSS unhealthy: no fix") is None and read("distrust v0: x") is None
    assert read("discredit v0: accuses v1, x") is None and read(b"distrust v3: x") is None
    assert read("discredit v4: accuses v1, consistent here") == Contradicted(4, 1)


@given(st.one_of(st.text(max_size=80), st.from_regex(r"discredit v[0-9]{1,4}: accuses v[0-9]{1,4}, .{0,45}")))
def test_any_statustext_gives_one_notice_or_none(text):
    said = read(text)
    assert len(announced(text)) == (0 if said is None else 1)
    if isinstance(said, Verdict):
        assert 1 <= said.neighbour <= 999
    if isinstance(said, Contradicted):
        assert 1 <= said.accuser <= 999 and 1 <= said.accused <= 999
