"""The ground station keeps each vehicle's latest status and SLAM map, refuses reports that name
another vehicle or one outside the swarm, and any bytes on a status key are kept, refused or a
DecodeError: never another exception."""

import logging

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from bus import messages as m
from bus.errors import DecodeError
from bus.landmark_map import LandmarkMap, encode_map
from bus.rejections import Rejections
from groundstation.vehicle_reports import VehicleReports


def _reports() -> VehicleReports:
    return VehicleReports(3, Rejections(logging.getLogger("test"), "ground station"))


def _status(vid: int, stamp_us: int = 0) -> bytes:
    return m.encode(m.VehicleStatus(vid, stamp_us, 10, 0, 0.0, 0.0, 0, 0, 0, 0))


def _map(vid: int) -> bytes:
    return encode_map(LandmarkMap(vid, 1_000_000, np.zeros((1, 2)), np.eye(2)[None] * 0.1))


def test_the_latest_status_and_map_of_each_vehicle_are_kept():
    reports = _reports()
    for payload in (_status(2, 0), _status(2, 500_000), _map(2)):
        reports.offer(2, payload)
    assert set(reports.statuses) == {2} and reports.statuses[2].stamp_us == 500_000
    assert set(reports.maps) == {2} and reports.maps[2].stamp_us == 1_000_000
    assert not reports.rejections.counts


def test_a_report_for_another_vehicle_or_outside_the_swarm_is_refused():
    reports = _reports()
    reports.offer(1, _status(2))  # vehicle 1's key, vehicle 2's status
    reports.offer(3, _map(1))  # vehicle 3's key, vehicle 1's map
    reports.offer(7, _status(7))  # a swarm of 3
    assert not reports.statuses and not reports.maps
    assert reports.rejections.counts == {"impersonation": 2, "unknown_vehicle": 1}


@given(st.binary(max_size=256), st.integers(1, 250))
def test_any_bytes_are_kept_refused_or_a_decode_error(payload, vid):
    reports = _reports()
    try:
        reports.offer(vid, payload)
    except DecodeError:
        pass
    assert set(reports.statuses) <= {1, 2, 3} and set(reports.maps) <= {1, 2, 3}


def test_a_final_status_is_kept_whatever_order_the_statuses_arrive_in():
    """The last periodic status and the final one of a vehicle share a stamp and a key; the summary
    reads the final one's counts even if the periodic one is handled after it."""
    periodic = m.encode(m.VehicleStatus(1, 60_000_000, 3000, 0, 0.0, 0.0, 0, 0, 0, 0))
    final = m.encode(m.VehicleStatus(1, 60_000_000, 3001, 0, 0.0, 0.0, 0, 0, 0, 0, final=True))
    earlier = m.encode(m.VehicleStatus(1, 59_000_000, 2951, 0, 0.0, 0.0, 0, 0, 0, 0))
    for order in ((periodic, final), (final, periodic), (final, earlier, periodic)):
        reports = _reports()
        for payload in order:
            reports.offer(1, payload)
        assert reports.statuses[1].final and reports.statuses[1].cycles == 3001
