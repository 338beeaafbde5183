"""What a vehicle sends: its signed MAVLink stream (ODOMETRY at ``mavlink_rate_hz``, HEARTBEAT and
ESTIMATOR_STATUS at 1 Hz, STATUSTEXT for notices), the V2V broadcast at every ranging epoch (its
estimate, or a NoEstimate ODOMETRY before it has one; then an accusation frame per neighbour its
monitor distrusts on its own evidence), its loop statistics and its lockstep
acknowledgements. A vehicle told to lie or to accuse (the ``lie`` and ``accuse`` faults, vehicle.process.lies)
changes only its V2V broadcast, signed with its own key on a second link (its accusations on the
third, as its honest ones): its MAVLink to the ground station stays honest.

MAVLink is a byte stream: the frames of one lockstep tick travel as one message (as several frames
share one UDP datagram); in realtime each cycle's frames go out at once.
"""

from __future__ import annotations

from collections import deque

from bus import messages as m
from bus.clock_config import ClockMode
from bus.config import VehicleProcessConfig
from bus.estimate import PoseEstimate
from bus.faults import Accuse, Lie
from bus.landmark_map import LandmarkMap, encode_map
from bus.mavlink_codec import MAX_ACCUSED, MavlinkEncoder, status_of
from bus.session import Bus
from vehicle.estimators.filter import Filter
from vehicle.process.lies import active_lies, false_accusations, longest_stale_s, told
from vehicle.process.v2v import send_turn_us


class Outbound:
    def __init__(self, bus: Bus, config: VehicleProcessConfig, vehicle_id: int, *, signing_key: bytes | None) -> None:
        keys, vc = bus.keys, config.vehicle
        self.vehicle_id, self.altitude_m = vehicle_id, config.altitude_m
        self.encoder = MavlinkEncoder(vehicle_id=vehicle_id, signing_key=signing_key)
        self._lie_encoder = MavlinkEncoder(vehicle_id=vehicle_id, signing_key=signing_key, link_id=1)
        self._accuser = MavlinkEncoder(vehicle_id=vehicle_id, signing_key=signing_key, link_id=2)
        self.mavlink_publisher = self._mavlink = bus.publisher(keys.mavlink(vehicle_id))
        self.v2v_publisher = self._v2v = bus.publisher(keys.v2v(vehicle_id))
        # the addressed publishers, one per neighbour: in realtime declared up front (a declaration is a
        # round trip to the router, which an overloaded swarm must not wait for mid-run), in lockstep
        # as listeners first appear (nothing there waits on the wall clock)
        self._bus, self._neighbours = bus, frozenset(j for j in range(1, config.vehicles + 1) if j != vehicle_id)
        realtime = config.clock.mode is ClockMode.REALTIME
        self._v2v_to = {j: bus.publisher(keys.v2v_to(vehicle_id, j)) for j in (self._neighbours if realtime else ())}
        self.ack_publisher = self._ack = bus.publisher(keys.ack(vehicle_id))
        self._status = bus.publisher(keys.status(vehicle_id))
        self._v2v_period_us = round(1e6 / config.sensors.ranging_rate_hz)
        self._mavlink_period_us = round(1e6 / vc.mavlink_rate_hz)
        self._heartbeat_us, self._status_period_us = round(vc.heartbeat_period_s * 1e6), round(vc.status_period_s * 1e6)
        self._next_heartbeat_us = 0
        self._next_status_us = 0
        self._frames: list[bytes] = []
        # realtime: an epoch's V2V frames wait for this vehicle's turn (when, frame, listeners)
        cycle_us, wait_us = round(1e6 / vc.loop_rate_hz), round(vc.cooperation.latency_s * 1e6)
        self._turn_us = send_turn_us(vehicle_id, cycle_us, wait_us) if realtime else 0
        self._held: deque[tuple[int, bytes, tuple[int, ...]]] = deque()
        self._past: deque[PoseEstimate] = deque()  # the broadcast epochs' estimates a stale lie replays
        self.v2v_sent = 0
        self.acked_tick: int | None = None  # the last tick acknowledged

    def cycle(
        self,
        t_us: int,
        estimator: Filter,
        reset_counter: int,
        listeners: tuple[int, ...] | None = None,
        behaviour: tuple[Lie | Accuse, ...] = (),
    ) -> None:
        """Encode this cycle's frames (kept until ``flush``); at the ranging epochs send the V2V frame to
        ``listeners`` (the vehicles that range with this one now), or to every vehicle (None), as the
        plan's lies and accusations of this vehicle (``behaviour``) have it; addressed frames go at this
        vehicle's turn (``send_turn_us``), sent before the cycle's own."""
        self.send_held(t_us)
        notices = estimator.notices.take()
        for notice in notices:
            self._frames += [  # when it was said, then what
                self.encoder.system_time(notice.stamp_us),
                self.encoder.statustext(notice.severity, notice.text[:50]),
            ]
        on_v2v, on_mavlink = self.broadcasts_at(t_us), self._on_mavlink(t_us)
        if not estimator.initialized:
            if on_v2v:  # neighbours in lockstep wait for every epoch's broadcast: say there is none
                self._send_v2v(t_us, self.encoder.no_estimate(t_us, reset_counter), listeners)
            return
        if any(n.status_changed for n in notices):
            self._frames.append(self.encoder.estimator_status(status_of(estimator.health(t_us))))
        if on_v2v or on_mavlink:
            pose = estimator.estimate(t_us)
            odometry = self.encoder.pose_odometry(pose, altitude_m=self.altitude_m, reset_counter=reset_counter)
            if on_mavlink:
                self._frames.append(odometry)
            if on_v2v:  # the V2V packet {id, x_hat, P, t}, and whom its monitor distrusts
                accused = sorted(set(estimator.accused()) | false_accusations(behaviour, self.vehicle_id, t_us / 1e6))
                accusations = b"".join(self._accuser.accusation(t_us, j) for j in accused[:MAX_ACCUSED])
                frame = self._v2v_frame(odometry, pose, t_us, reset_counter, behaviour) + accusations
                self._send_v2v(t_us, frame, listeners)
        if self._heartbeat_due(t_us):
            self._frames += [self.encoder.heartbeat(), self.encoder.estimator_status(status_of(estimator.health(t_us)))]
            self._next_heartbeat_us = t_us + self._heartbeat_us

    def quiet_at(self, t_us: int) -> bool:
        """Whether the cycle at ``t_us`` sends nothing on a schedule: no ODOMETRY, no V2V broadcast, no
        heartbeat and no loop statistics (notices aside)."""
        return not (
            self.broadcasts_at(t_us) or self._on_mavlink(t_us) or self._heartbeat_due(t_us) or self._status_is_due(t_us)
        )

    def broadcasts_at(self, t_us: int) -> bool:
        """Whether the cycle at ``t_us`` is a V2V epoch (its broadcast goes out)."""
        return t_us % self._v2v_period_us == 0

    def _on_mavlink(self, t_us: int) -> bool:
        return t_us % self._mavlink_period_us == 0

    def _heartbeat_due(self, t_us: int) -> bool:
        return t_us >= self._next_heartbeat_us

    def _status_is_due(self, t_us: int) -> bool:
        return t_us >= self._next_status_us

    def _v2v_frame(
        self, honest: bytes, estimate: PoseEstimate, t_us: int, reset_counter: int, behaviour: tuple
    ) -> bytes:
        """The honest frame, or the estimate as the plan's active lies tell it."""
        stale_s = longest_stale_s(behaviour, self.vehicle_id)
        if stale_s:
            self._past.append(estimate)
            while self._past[0].stamp_us < t_us - round((stale_s + 1.0) * 1e6):
                self._past.popleft()
        active = active_lies(behaviour, self.vehicle_id, t_us / 1e6)
        if not active:
            return honest
        told_estimate = told(estimate, active, self._past)
        return self._lie_encoder.pose_odometry(told_estimate, altitude_m=self.altitude_m, reset_counter=reset_counter)

    def _send_v2v(self, t_us: int, frame: bytes, listeners: tuple[int, ...] | None) -> None:
        """Broadcast (``listeners`` None: counted for lockstep's V2V barrier) or one copy per listener,
        at this vehicle's turn after the epoch ``t_us`` (realtime; lockstep's turn is the epoch)."""
        if listeners is None:
            self._v2v.put(frame)
            self.v2v_sent += 1
        elif self._turn_us:
            self._held.append((t_us + self._turn_us, frame, listeners))
        else:
            self._send_addressed(frame, listeners)

    def send_held(self, now_us: int | None = None) -> None:
        """Send the V2V frames held for this vehicle's turn: those due by ``now_us`` (None: all, at the
        run's end)."""
        while self._held and (now_us is None or self._held[0][0] <= now_us):
            _, frame, listeners = self._held.popleft()
            self._send_addressed(frame, listeners)

    def _send_addressed(self, frame: bytes, listeners: tuple[int, ...]) -> None:
        for j in listeners:
            publisher = self._v2v_to.get(j)
            if publisher is None and j in self._neighbours:  # the world names only this swarm's vehicles
                publisher = self._v2v_to[j] = self._bus.publisher(self._bus.keys.v2v_to(self.vehicle_id, j))
            if publisher is not None:
                publisher.put(frame)

    def flush(self) -> None:
        """Publish the frames encoded since the last flush as one message."""
        if self._frames:
            self._mavlink.put(b"".join(self._frames))
            self._frames = []

    def status_due(self, t_us: int) -> bool:
        """Whether the loop statistics go out after the cycle at ``t_us`` (the next one is then due a
        period later)."""
        if self._status_is_due(t_us):
            self._next_status_us = t_us + self._status_period_us
            return True
        return False

    def status(self, status: m.VehicleStatus, landmark_map: LandmarkMap | None = None) -> None:
        """The loop statistics, after the map (when the estimator keeps one) on the same key."""
        if landmark_map is not None:
            self._status.put(encode_map(landmark_map))
        self._status.put(m.encode(status))

    def ack(self, tick: int) -> None:
        self.acked_tick = tick
        self._ack.put(m.encode(m.TickAck(self.vehicle_id, tick, self.v2v_sent)))
