"""The vehicle-to-vehicle side of a vehicle: neighbours' broadcast estimates, and ranging
measurements that wait ``latency_us`` for the neighbour's estimate of the same instant.

A ranging measurement stamped t becomes a CooperativeFix at the first cycle at or after
t + latency, once the neighbour's ODOMETRY for the broadcast epoch at or before t has been heard
(the world makes no ranging to or from a comm-jammed vehicle); it reaches the estimator through the
fusion horizon (which replays from t). The fixed wait makes lockstep runs reproducible: what is
fused at a cycle never depends on how fast the neighbour's packet travelled. The simulated world
ranges at the epochs; a replayed camera sights a robot whenever it does, so the neighbour's
position is carried from its epoch e to t along its broadcast heading at its broadcast speed,
p(t) = p(e) + v (t - e) [cos yaw, sin yaw], its covariance grown by (var v + v^2 var yaw) (t - e)^2
on both axes (t - e is under one broadcast period). A neighbour's sighting of this vehicle relayed
to it (``SeenBy``) waits the same way for the observer's broadcast and becomes a SeenFix with the
observer's whole pose and its covariance carried to t (``Broadcast.carried_pose``): the bearing was
measured from the observer's heading, so the heading's uncertainty counts.

Neighbours' frames are kept as they arrive and decoded and checked when a measurement pairs with
them (the radio ranges at most a few peers per epoch; where every neighbour's broadcast is heard, in
replays, four frames in five were decoded for nothing in a 20-vehicle swarm; a simulation sends
each frame only to the vehicles that range with its sender, on ``v/j/v2v/<receiver>``, so what a
vehicle files per epoch does not grow with the swarm): the sender must be the vehicle whose key it
came on, the covariance must be usable; what fails is counted then. Authenticity rests on the
router: only vehicle j's login may publish on ``v/j/v2v`` and ``v/j/v2v/*`` (bus.access); a vehicle
holds no other vehicle's signing key.
"""

from __future__ import annotations

import heapq
import itertools
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from bus import messages as m
from bus.angles import wrap_angle
from bus.errors import DecodeError
from bus.estimate import PoseEstimate
from bus.mavlink_codec import (
    MAX_ACCUSED,
    Accusation,
    MavlinkDecoder,
    MavlinkRejected,
    NoEstimate,
    split_frames,
)
from bus.rejections import Rejections
from vehicle.models.cooperative_fixes import CooperativeFix, SeenFix

HISTORY = 64  # broadcasts kept per neighbour (12 s at 5 Hz)
MAX_COPIES = 4  # frames kept per neighbour and epoch (a link fault duplicates; more is a flood)
MAX_WAITING = 10_000


def fusion_turn_us(vehicle_id: int, cycle_us: int, v2v_period_us: int, room_us: int) -> int:
    """Realtime: how long after its wait for the neighbours' estimates vehicle ``vehicle_id`` fuses an
    epoch's ranging, in whole loop cycles of ``cycle_us``: vehicles take turns, a cycle apart, over
    the first half of the V2V period ``v2v_period_us`` (so the fixes are in the vehicle's next
    broadcast) and within ``room_us``, what the fusion horizon leaves beyond the wait. Every vehicle
    ranges at the same epochs, and fusing them replays the fusion horizon from the epoch: at one
    shared cycle that was 20 vehicles x 2.1 ms of CPU due within one 20 ms period on two cores, the
    cycles behind it late (docs/decisions/performance.md). Lockstep needs no turns (it waits for
    whoever is late) and keeps the plain wait."""
    slots = max(1, min(v2v_period_us // 2, room_us) // cycle_us)
    return ((vehicle_id - 1) % slots) * cycle_us


def send_turn_us(vehicle_id: int, cycle_us: int, wait_us: int) -> int:
    """Realtime: how long after a ranging epoch vehicle ``vehicle_id`` sends that epoch's V2V frames,
    in whole loop cycles of ``cycle_us``: vehicles take turns, a cycle apart, over the first half of
    ``wait_us``, the wait its neighbours give the frames (the other half is the frames' time on the
    way). At one shared cycle every vehicle's epoch frames, their copies through the router and their
    arrivals filled the epoch's period with its GNSS fixes and checkpoints, and the world's next tick
    waited for the cores (docs/decisions/performance.md). What a frame says is fixed at the epoch;
    lockstep sends it there (its neighbours wait for it)."""
    slots = wait_us // 2 // cycle_us + 1
    return ((vehicle_id - 1) % slots) * cycle_us


@dataclass(frozen=True)
class Broadcast:
    """What a neighbour's broadcast tells about it: pose [x m, y m, yaw rad] (3,) and its covariance
    (3, 3), forward speed m/s and yaw rate rad/s with their variances."""

    pose: np.ndarray
    pose_cov: np.ndarray
    speed_mps: float
    speed_var: float
    yaw_rate_radps: float = 0.0
    yaw_rate_var: float = 0.0
    accuses: frozenset[int] = frozenset()  # the neighbours its sender's monitor distrusts

    def carried(self, dt_us: int) -> tuple[np.ndarray, np.ndarray]:
        """Position (2,) and covariance (2, 2) ``dt_us`` after the broadcast (module docstring);
        itself at 0."""
        xy, cov = self.pose[:2], self.pose_cov[:2, :2]
        if dt_us == 0:
            return xy, cov
        dt, yaw = dt_us * 1e-6, float(self.pose[2])
        step = self.speed_mps * dt * np.array([np.cos(yaw), np.sin(yaw)])
        spread = (self.speed_var + self.speed_mps**2 * self.pose_cov[2, 2]) * dt * dt
        return xy + step, cov + spread * np.eye(2)

    def carried_pose(self, dt_us: int) -> tuple[np.ndarray, np.ndarray]:
        """Pose (3,) and covariance (3, 3) ``dt_us`` after the broadcast: unicycle motion at the
        broadcast speed and yaw rate, linearised (F P F^T + speed and yaw-rate variances times dt^2)."""
        if dt_us == 0:
            return self.pose, self.pose_cov
        dt, yaw = dt_us * 1e-6, float(self.pose[2])
        heading = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        F = np.eye(3)
        F[:2, 2] = self.speed_mps * dt * np.array([-heading[1], heading[0]])
        noise = self.speed_var * dt * dt * np.outer(heading, heading)
        noise[2, 2] = self.yaw_rate_var * dt * dt
        pose = self.pose + dt * np.array(
            [self.speed_mps * heading[0], self.speed_mps * heading[1], self.yaw_rate_radps]
        )
        pose[2] = wrap_angle(pose[2])
        return pose, F @ self.pose_cov @ F.T + noise


@dataclass
class _Epoch:
    """A neighbour's frames for one broadcast epoch, decoded on first use: the last good one counts."""

    frames: list[bytes]
    decoded: int = 0
    broadcast: Broadcast | None = None


class V2V:
    def __init__(self, vehicle_id: int, *, latency_us: int, rejections: Rejections, period_us: int) -> None:
        self.vehicle_id, self.latency_us, self.rejections = vehicle_id, latency_us, rejections
        self.period_us = period_us  # between the neighbours' broadcast epochs
        self._decoder = MavlinkDecoder()  # neighbours' keys are not ours to hold: no authentication here
        self._heard: dict[int, OrderedDict[int, _Epoch]] = {}
        self._waiting: list[tuple[int, int, m.RangeBearing]] = []
        self._order = itertools.count()
        self.sent = 0
        self.missing = 0

    def hear(self, sender: int, stamp_us: int, frame: bytes) -> None:
        """A neighbour's ODOMETRY frame (after link faults): kept by stamp until a measurement needs it."""
        history = self._heard.get(sender)
        if history is None:
            history = self._heard[sender] = OrderedDict()
        epoch = history.get(stamp_us)
        if epoch is None:
            history[stamp_us] = _Epoch([frame])
            while len(history) > HISTORY:
                history.popitem(last=False)
        elif len(epoch.frames) < MAX_COPIES:
            epoch.frames.append(frame)
        else:
            self.rejections.reject("unexpected", f"v2v from {sender}", f"over {MAX_COPIES} frames for epoch {stamp_us}")

    def _broadcast(self, sender: int, stamp_us: int) -> Broadcast | None:
        """The neighbour's broadcast of epoch ``stamp_us``: its frames decoded now if not yet."""
        epoch = self._heard.get(sender, {}).get(stamp_us)
        if epoch is None:
            return None
        for frame in epoch.frames[epoch.decoded :]:
            epoch.broadcast = self._decoded(sender, stamp_us, frame) or epoch.broadcast
        epoch.decoded = len(epoch.frames)
        return epoch.broadcast

    def _decoded(self, sender: int, stamp_us: int, payload: bytes) -> Broadcast | None:
        """One broadcast checked: None (counted) if it is not a usable estimate of ``sender`` at
        ``stamp_us`` followed by at most ``MAX_ACCUSED`` accusations of that sender and epoch."""
        frames, trailing = split_frames(payload)
        try:
            if not frames or trailing or len(frames) > 1 + MAX_ACCUSED:
                raise DecodeError(f"{len(frames)} MAVLink frames and {trailing} trailing bytes")
            est = self._decoder.decode_pose(frames[0])
            accusations = [self._decoder.decode(frame) for frame in frames[1:]]
        except MavlinkRejected as exc:
            self.rejections.reject(exc.reason, f"v2v from {sender}", str(exc))
            return None
        except DecodeError as exc:
            self.rejections.reject("malformed", f"v2v from {sender}", str(exc))
            return None
        if isinstance(est, NoEstimate) and est.vehicle_id == sender and est.time_usec == stamp_us:
            return None  # the neighbour had no estimate at that epoch
        if not isinstance(est, PoseEstimate) or est.vehicle_id != sender or est.stamp_us != stamp_us:
            self.rejections.reject("impersonation", f"v2v from {sender}", "sender or stamp differs from the frame's")
            return None
        accused = _accused(accusations, sender, stamp_us)
        if accused is None:
            self.rejections.reject("unexpected", f"v2v from {sender}", "not an accusation by the sender at its epoch")
            return None
        return Broadcast(
            est.pose, est.pose_cov, est.speed_mps, est.speed_var, est.yaw_rate_radps, est.yaw_rate_var, accused
        )

    def hold(self, measurement: m.RangeBearing | m.SeenBy) -> bool:
        """Keep a ranging measurement, or a neighbour's sighting of this vehicle, until the
        neighbour's broadcast is due; False when full."""
        if len(self._waiting) >= MAX_WAITING:
            self.rejections.reject("inbox_full", "ranging waiting for V2V", "too many waiting")
            return False
        heapq.heappush(self._waiting, (measurement.stamp_us, next(self._order), measurement))
        return True

    def revises(self, t_us: int) -> bool:
        """Whether a measurement stamped at or before ``t_us`` is still waiting for its neighbour's
        broadcast: the estimate at ``t_us`` will be revised when it is fused."""
        return bool(self._waiting) and self._waiting[0][0] <= t_us

    def awaited(self, now_us: int) -> list[tuple[int, int]]:
        """(neighbour, stamp) of every ranging measurement that matures by ``now_us``: whose
        broadcasts the cycle at ``now_us`` pairs them with."""
        if not self._waiting or self._waiting[0][0] + self.latency_us > now_us:  # the heap's earliest: none matures
            return []
        return [(_peer(msg), self.epoch(stamp)) for stamp, _, msg in self._waiting if stamp + self.latency_us <= now_us]

    def epoch(self, stamp_us: int) -> int:
        """The neighbours' broadcast epoch at or before ``stamp_us``."""
        return stamp_us - stamp_us % self.period_us

    def mature(self, now_us: int) -> list[CooperativeFix | SeenFix]:
        """Measurements whose wait is over, paired with the neighbour's estimate carried to their stamp."""
        out: list[CooperativeFix | SeenFix] = []
        while self._waiting and self._waiting[0][0] + self.latency_us <= now_us:
            msg = heapq.heappop(self._waiting)[2]
            epoch = self.epoch(msg.stamp_us)
            found = self._broadcast(_peer(msg), epoch)
            if found is None:
                self.missing += 1
                continue
            if isinstance(msg, m.SeenBy):
                out.append(
                    SeenFix(
                        msg.vehicle_id,
                        msg.stamp_us,
                        msg.seq,
                        msg.observer_id,
                        msg.range_m,
                        msg.bearing_rad,
                        msg.covariance,
                        *found.carried_pose(msg.stamp_us - epoch),
                        found.accuses,
                    )
                )
            else:
                out.append(
                    CooperativeFix(
                        msg.vehicle_id,
                        msg.stamp_us,
                        msg.seq,
                        msg.target_id,
                        msg.range_m,
                        msg.bearing_rad,
                        msg.covariance,
                        *found.carried(msg.stamp_us - epoch),
                        found.accuses,
                    )
                )
        return out


def _accused(accusations: list, sender: int, stamp_us: int) -> frozenset[int] | None:
    """The neighbours ``sender``'s accusations at the epoch ``stamp_us`` name (other vehicles, ids
    1-255); None when one is not such an accusation."""
    accused = set()
    for a in accusations:
        valid = isinstance(a, Accusation) and a.vehicle_id == sender and a.time_boot_ms == (stamp_us // 1000) % 2**32
        if not (valid and 1 <= a.neighbour <= 255 and a.neighbour != sender):
            return None
        accused.add(a.neighbour)
    return frozenset(accused)


def _peer(msg: m.RangeBearing | m.SeenBy) -> int:
    """The neighbour whose broadcast a measurement pairs with: the one ranged, or the observer."""
    return msg.observer_id if isinstance(msg, m.SeenBy) else msg.target_id
