"""Every estimator's state is one object, copied by one rule: a replay from a snapshot continues
exactly as the original did, for every estimator in the registry, and the rule refuses what it
cannot copy instead of sharing it silently."""

import dataclasses

import numpy as np
import pytest

from bus.config import build_config
from bus.estimators import ESTIMATORS
from experiments.harness import vehicle_feed
from vehicle.estimators import get_estimator
from vehicle.estimators.state import FilterState, copied, frozen

PERIOD_US = 20_000


def _config(estimator: str):
    sections = {
        "world": {"vehicles": 1, "seed": 5, "trajectories": ["circle"]},
        "clock": {"duration_s": 6.0},
        "sensors": {"camera_rate_hz": 10 if estimator.endswith("ekf-slam") else 0},
        "vehicle": {"estimator": estimator, "cooperation": {"enabled": False}},
    }
    if estimator == "known-map":
        sections["vehicle"]["landmarks"] = [(1, 5.0, 5.0)]
    if estimator == "ar-ekf-slam-3d":
        sections["sensors"]["camera3d"] = {"rate_hz": 10}
    return build_config(sections)


def _run(estimator, feed, start_us: int, end_us: int) -> None:
    for t in range(start_us, end_us + 1, PERIOD_US):
        for _, msg in feed:
            if t - PERIOD_US < msg.stamp_us <= t or (t == start_us == 0 and msg.stamp_us == 0):
                estimator.handle(msg)
        estimator.cycle(t)


def _fingerprint(estimator) -> tuple:
    s = estimator.state
    if hasattr(s, "slam"):  # the 3-D estimator: its back end holds the state
        return s.slam.x.tobytes(), s.slam.P.tobytes(), s.time_us, repr(s.counters), repr(s.slam.book)
    books = tuple(
        repr(dataclasses.asdict(b)) if dataclasses.is_dataclass(b) else repr(b) for b in (s.landmarks, s.errors)
    )
    return s.x.tobytes(), s.P.tobytes(), s.time_us, repr(s.counters), books


@pytest.mark.parametrize("name", list(ESTIMATORS))
def test_a_replay_from_a_snapshot_continues_exactly_as_the_original(name):
    config = _config(name)
    feed = vehicle_feed(config)
    estimator = get_estimator(config.for_vehicle(), 1)
    _run(estimator, feed, 0, 3_000_000)
    snapshot = estimator.snapshot()
    _run(estimator, feed, 3_020_000, 6_000_000)
    first = _fingerprint(estimator)
    estimator.restore(snapshot)
    _run(estimator, feed, 3_020_000, 6_000_000)
    assert _fingerprint(estimator) == first
    estimator.restore(snapshot)  # the snapshot stays reusable
    _run(estimator, feed, 3_020_000, 6_000_000)
    assert _fingerprint(estimator) == first


def test_the_copy_rule_copies_arrays_shares_read_only_ones_and_refuses_the_unknown():
    writable, read_only = np.zeros(3), frozen(np.ones(3))
    assert copied(writable) is not writable and copied(read_only) is read_only
    with pytest.raises(ValueError):
        read_only[0] = 2.0  # numpy itself keeps the shared array unchanged
    nested = {"a": [1, 2]}
    assert copied(nested) is not nested
    with pytest.raises(TypeError, match="cannot copy"):
        copied(object())


def test_every_field_of_the_state_is_copied_or_immutable():
    estimator = get_estimator(_config("known-map").for_vehicle(), 1)
    state = estimator.state
    twin = state.copy()
    for field in dataclasses.fields(FilterState):
        a, b = getattr(state, field.name), getattr(twin, field.name)
        if a is b:
            assert a is None or isinstance(a, (int, float, str, bool, tuple)), field.name


def test_the_registry_names_every_allowed_estimator_and_each_builds():
    from bus.config import VehicleConfig

    allowed = VehicleConfig.model_json_schema()["properties"]["estimator"]["enum"]
    assert sorted(allowed) == sorted(ESTIMATORS)
    for name in ESTIMATORS:
        assert get_estimator(_config(name).for_vehicle(), 1).name == name
