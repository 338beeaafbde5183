"""What the ground station does with each vehicle's MAVLink once its intake has passed a frame:
estimates go to scoring (and their delay is measured), GNSS health changes and what a vehicle says
become events, stamped with the vehicle's own time, and every frame may be forwarded to a GCS."""

from __future__ import annotations

from collections.abc import Callable

from bus.mavlink_codec import EstimatorStatus, StateEstimate, StatusText, SystemTime
from bus.rejections import Rejections
from groundstation.mavlink_in import MavlinkIntake, said_at
from groundstation.mavlink_out import MavlinkForwarder
from groundstation.rundir import RunDirectory
from groundstation.scoring import Scorer
from groundstation.vehicle_says import announced

EventAt = Callable[..., None]  # (kind, stamp_us, **fields): a counted event


class VehicleStreams:
    """Per vehicle: the newest estimate's stamp, the estimates' delay behind the swarm's time
    (count, sum, max in us), the GNSS glitch flag, and the time its last SYSTEM_TIME said."""

    def __init__(
        self,
        intake: MavlinkIntake,
        scorer: Scorer,
        run: RunDirectory,
        event_at: EventAt,
        rejections: Rejections,
        forwarder: MavlinkForwarder | None = None,
    ) -> None:
        self.intake, self.scorer, self.run, self.event_at = intake, scorer, run, event_at
        self.rejections, self.forwarder = rejections, forwarder
        self.latency_us: dict[int, list[int]] = {}
        self.latest_estimate_us: dict[int, int] = {}
        self.gnss_glitch: dict[int, bool] = {}
        self.said_us: dict[int, int | None] = {}  # the time its last SYSTEM_TIME said, until a STATUSTEXT

    def frame(self, vid: int, frame: bytes, sim_time_us: int) -> None:
        """One frame of vehicle ``vid`` that its link delivered, at the swarm's time ``sim_time_us``."""
        decoded = self.intake.decode(vid, frame, sim_time_us)
        if decoded is None:
            return
        if self.forwarder is not None:
            self.forwarder.forward(frame)
        if isinstance(decoded, StateEstimate):
            lat = self.latency_us.setdefault(vid, [0, 0, 0])  # count, sum, max (us)
            delay = sim_time_us - decoded.time_usec
            lat[0], lat[1], lat[2] = lat[0] + 1, lat[1] + delay, max(lat[2], delay)
            if not self.scorer.add_estimate(decoded):
                self.rejections.reject("pending_full", f"MAVLink of vehicle {vid}", "scoring backlog full")
            self.latest_estimate_us[vid] = max(decoded.time_usec, self.latest_estimate_us.get(vid, -1))
        elif isinstance(decoded, EstimatorStatus):
            self._estimator_status(decoded)
        elif isinstance(decoded, SystemTime):
            self.said_us[decoded.vehicle_id] = said_at(decoded.time_boot_ms, sim_time_us)
        elif isinstance(decoded, StatusText):
            self._statustext(decoded, sim_time_us)

    def _statustext(self, said: StatusText, sim_time_us: int) -> None:
        """A vehicle's message, and the events it announces, stamped with the SYSTEM_TIME the vehicle
        sent just before it (else, or if that was not near the swarm's time, the clock tick)."""
        stamp = self.said_us.pop(said.vehicle_id, None)
        stamp = sim_time_us if stamp is None else stamp
        self.run.event("vehicle_message", stamp, vehicle=said.vehicle_id, severity=said.severity, text=said.text)
        for kind, fields in announced(said.text):
            self.event_at(kind, stamp, vehicle=said.vehicle_id, **fields)

    def _estimator_status(self, status: EstimatorStatus) -> None:
        """GNSS health changes (the GPS glitch flag) become events, stamped with the vehicle's time."""
        if self.run.recording is not None:
            self.run.recording.health(status)
        was = self.gnss_glitch.get(status.vehicle_id, False)
        self.gnss_glitch[status.vehicle_id] = status.gps_glitch
        if status.gps_glitch != was:
            kind = "gnss_unhealthy" if status.gps_glitch else "gnss_healthy"
            self.event_at(
                kind, status.time_usec, vehicle=status.vehicle_id, test_ratio=round(status.pos_horiz_ratio, 3)
            )
