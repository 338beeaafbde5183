"""What vehicles report on their status key besides estimates: their loop statistics (VehicleStatus)
and, from SLAM vehicles, their landmark maps. Keeps the latest of each per vehicle; a report that
names another vehicle than the key it came on, or a vehicle outside the swarm, is refused."""

from __future__ import annotations

from typing import Any

from bus import messages as m
from bus.errors import DecodeError
from bus.landmark_map import LandmarkMap, decode_map
from bus.rejections import Rejections, counts_to_dict


class VehicleReports:
    """The latest status and map of each of ``vehicles`` vehicles (ids 1..vehicles)."""

    def __init__(self, vehicles: int, rejections: Rejections) -> None:
        self.vehicles, self.rejections = vehicles, rejections
        self.statuses: dict[int, m.VehicleStatus] = {}
        self.maps: dict[int, LandmarkMap] = {}

    def offer(self, vid: int, payload: bytes) -> None:
        """A payload from ``v/<vid>/status``: a VehicleStatus, else a landmark map; DecodeError (the
        status's) when it is neither."""
        try:
            status = m.decode(m.VehicleStatus, payload)
        except DecodeError as not_status:
            try:
                landmark_map = decode_map(payload)
            except DecodeError:
                raise not_status from None
            if self._belongs(vid, landmark_map.vehicle_id, "map"):
                self.maps[vid] = landmark_map
            return
        if self._belongs(vid, status.vehicle_id, "status") and not _older(status, self.statuses.get(vid)):
            self.statuses[vid] = status

    def offer_and_show(self, vid: int, payload: bytes, recording: Any | None) -> None:
        """``offer``, and a map or status that is new shown in the live view and run.mcap
        (``recording``, a groundstation.recording.Recording, or None): with a status, the vehicle's
        first rejected input of each kind (its status counts them)."""
        before_map, before_status = self.maps.get(vid), self.statuses.get(vid)
        self.offer(vid, payload)
        if recording is None:
            return
        landmark_map, status = self.maps.get(vid), self.statuses.get(vid)
        if landmark_map is not None and landmark_map is not before_map:
            recording.landmarks(landmark_map)
        if status is not None and status is not before_status:
            recording.loop(status)
            was = counts_to_dict(before_status.rejected) if before_status is not None else {}
            for reason, count in counts_to_dict(status.rejected).items():
                if not was.get(reason):
                    text = f"vehicle {status.vehicle_id} rejected input ({reason}): {count} so far"
                    recording.message(status.stamp_us, text, name=f"vehicle-{status.vehicle_id}")

    def _belongs(self, vid: int, claimed: int, what: str) -> bool:
        """True when a ``what`` claiming vehicle ``claimed`` may be kept for the key's vehicle ``vid``."""
        if claimed == vid and vid <= self.vehicles:
            return True
        self.rejections.reject(
            "impersonation" if claimed != vid else "unknown_vehicle",
            f"status of vehicle {vid}",
            f"{what} of vehicle {claimed}",
        )
        return False


def _older(status: m.VehicleStatus, kept: m.VehicleStatus | None) -> bool:
    """True when ``status`` says less than the one kept: a final status is never replaced by a
    periodic one, nor a later one by an earlier one, whatever order they arrive in (statuses are
    cumulative; a restarted vehicle counts from zero again but its stamps go on)."""
    return kept is not None and (status.final, status.stamp_us) < (kept.final, kept.stamp_us)
