"""The replay world: a recorded MRCLAM data set played on sim time, in the shape of ``sim.world.World``
(``advance``, ``vehicle_ids``, ``faults``), so the world node runs either.

Sim time 0 is data set time ``replay.start_s``; robot ``replay.robots[i]`` flies as vehicle i + 1.
Each vehicle gets its launch prior at 0 (the Vicon pose, perturbed by the datasheet's prior sigma
from the world seed), its recorded odometry stamped when it takes effect (``replay.odom_lag_s``
later; the sample in force at the start, stamped 0, then the rest; a repeated stamp keeps the
first), its landmark sightings (``landmark`` rows) and its sightings of replayed robots
(``ranging`` rows), stamped when the image was taken (``replay.camera_latency_s`` before the
recorded stamp), each with its robot's calibrated covariance (``replay.sighting_sigmas``: range
sigma per metre of the range read, bearing sigma; the datasheet's range and bearing sigma without).
Every robot sighting that is delivered is also relayed to the robot seen (``seen`` rows: observer,
range, bearing, covariance), as the observer's radio would pass it on, so both ends can use it
(``replay.relay_sightings``, on by default).
Sightings of robots that are not replayed are counted and skipped. Truth is the Vicon track interpolated onto the
``truth_rate_hz`` grid, a row of NaN where Vicon has no pose (sim.mrclam.pose_at). Physical faults
apply as in the simulated world: blackouts of ``odom``, ``landmark`` or ``ranging``, comm jamming
at the true positions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bus.angles import wrap_angles
from bus.config import SwarmConfig
from bus.feed import CameraBlock
from bus.topics import Topic
from sim.mrclam import DataError, MrclamData, delayed, pose_at
from sim.mrclam_camera import rectified
from sim.physical_faults import PhysicalFaults

Block = tuple[np.ndarray, np.ndarray]  # stamps (k,) us, rows (k, w)


@dataclass
class ReplayOutput:
    """What one advance replayed: per vehicle, topic -> (stamps, first seq, rows); truth stamps (k,)
    and rows (k, N, 6) [x, y, theta, speed, yaw rate, height]."""

    feeds: dict[int, dict[str, tuple[np.ndarray, int, np.ndarray]]]
    truth_stamps: np.ndarray
    truth: np.ndarray

    def blocks(self, vehicle_id: int) -> dict[str, tuple[np.ndarray, int, np.ndarray]]:
        return self.feeds.get(vehicle_id, {})

    def camera(self, vehicle_id: int) -> CameraBlock | None:
        return None

    def listeners(self) -> dict[int, tuple[int, ...]]:
        """vehicle id -> the robots that sighted it in this advance (sorted), as sim.world's."""
        out: dict[int, set[int]] = {}
        for observer, topics in self.feeds.items():
            if Topic.RANGING in topics:
                for target in topics[Topic.RANGING][2][:, 0].astype(int).tolist():
                    out.setdefault(target, set()).add(observer)
        return {target: tuple(sorted(observers)) for target, observers in out.items()}


def _stamps_us(t_s: np.ndarray, start_s: float) -> np.ndarray:
    return np.round((t_s - start_s) * 1e6).astype(np.int64)


def odometry_rows(odometry: np.ndarray, start_s: float, end_s: float) -> Block:
    """The odometry in force at ``start_s`` (stamped 0) and every later sample up to ``end_s``;
    of samples sharing a stamp (us), the first."""
    before = np.flatnonzero(odometry[:, 0] <= start_s)
    inside = np.flatnonzero((odometry[:, 0] > start_s) & (odometry[:, 0] <= end_s))
    rows = odometry[np.concatenate([before[-1:], inside])]
    stamps = np.maximum(_stamps_us(rows[:, 0], start_s), 0)
    keep = np.concatenate([[True], np.diff(stamps) > 0]) if len(stamps) else np.zeros(0, bool)
    return stamps[keep], rows[keep, 1:3]


def sighting_rows(
    sightings: np.ndarray,
    start_s: float,
    end_s: float,
    vehicle_of: dict[int, int],
    sigmas: tuple[float, float],
    relative: bool,
) -> tuple[Block, Block, int]:
    """Landmark rows [id, range, bearing, cov (4)] and ranging rows [vehicle, range, bearing, cov (4)]
    of the sightings in (start_s, end_s], the covariance diagonal from ``sigmas`` (range, bearing),
    the range sigma per metre of the range read when ``relative``; robots (subjects 1-5) map through
    ``vehicle_of`` and are skipped (counted) when they are not replayed."""
    s = sightings[(sightings[:, 0] > start_s) & (sightings[:, 0] <= end_s)]
    stamps = _stamps_us(s[:, 0], start_s)
    range_sigma = sigmas[0] * s[:, 2] if relative else np.full(len(s), sigmas[0])
    cov = np.column_stack([range_sigma**2, np.zeros(len(s)), np.zeros(len(s)), np.full(len(s), sigmas[1] ** 2)])
    robot = s[:, 1] <= 5
    target = np.array([vehicle_of.get(int(r), 0) for r in s[robot, 1]], dtype=float)
    replayed = target > 0
    landmark = (stamps[~robot], np.column_stack([s[~robot, 1:4], cov[~robot]]))
    peers = (
        stamps[robot][replayed],
        np.column_stack([target[replayed], s[robot, 2:4][replayed], cov[robot][replayed]]),
    )
    return landmark, peers, int((~replayed).sum())


def relayed_sightings(feeds: dict[int, dict[str, tuple[np.ndarray, int, np.ndarray]]]) -> dict[int, Block]:
    """The robot sightings of one advance (``ranging`` blocks per observer) as each seen robot's
    ``seen`` rows [observer, range, bearing, cov (4)], in stamp order (observers in id order at one stamp)."""
    blocks = [
        (observer, *topics[Topic.RANGING]) for observer, topics in sorted(feeds.items()) if Topic.RANGING in topics
    ]
    if not blocks:
        return {}
    stamps = np.concatenate([block[1] for block in blocks])
    seen = np.concatenate([block[3][:, 0] for block in blocks]).astype(int)
    rows = np.concatenate(
        [np.column_stack([np.full(len(block[1]), float(block[0])), block[3][:, 1:]]) for block in blocks]
    )
    out = {}
    for vid in np.unique(seen).tolist():
        mine = np.flatnonzero(seen == vid)
        mine = mine[np.argsort(stamps[mine], kind="stable")]
        out[vid] = (stamps[mine], rows[mine])
    return out


class ReplayWorld:
    """A data set's robots as the world's vehicles: see the module docstring."""

    def __init__(self, config: SwarmConfig, data: MrclamData) -> None:
        replay, spec = config.replay, config.sensors
        self.config, self.faults = config, PhysicalFaults(config.faults)
        self.start_s, end_s = replay.start_s, replay.start_s + config.clock.duration_s
        self.robots = {i + 1: robot for i, robot in enumerate(replay.robots)}
        vehicle_of = {robot: vid for vid, robot in self.robots.items()}
        relative = bool(replay.sighting_sigmas)  # calibrated: range sigma per metre; else the datasheet's, in m
        sigmas = replay.sighting_sigmas or ((spec.range_sigma_m, spec.bearing_sigma_rad),) * len(self.robots)
        self._relay = replay.relay_sightings
        self.skipped_sightings = 0  # of robots not replayed (unknown barcodes: data.robots[r].unknown_barcodes)
        self._streams: dict[int, dict[str, Block]] = {}
        for vid, robot in self.robots.items():
            log = delayed(data.robots[robot], replay.odom_lag_s, replay.camera_latency_s)
            if replay.readouts:
                log = rectified(log, replay.readouts[vid - 1])
            landmark, peers, skipped = sighting_rows(
                log.sightings, self.start_s, end_s, vehicle_of, sigmas[vid - 1], relative
            )
            if robot in replay.withhold_landmarks:
                landmark = (landmark[0][:0], landmark[1][:0])
            self.skipped_sightings += skipped
            self._streams[vid] = {
                Topic.PRIOR: self._prior(vid, log.groundtruth),
                Topic.ODOM: odometry_rows(log.odometry, self.start_s, end_s),
                Topic.LANDMARK: landmark,
                Topic.RANGING: peers,
            }
        self._cursor = {(vid, topic): 0 for vid, topics in self._streams.items() for topic in topics}
        self._sent = dict.fromkeys(self._cursor, 0)  # sequence numbers count what was sent
        step_us = round(1e6 / spec.truth_rate_hz)
        grid = np.arange(0, round(config.clock.duration_s * 1e6) + 1, step_us, dtype=np.int64)
        self._truth_stamps = grid
        self._truth = np.stack([self._truth_rows(data.robots[r].groundtruth, grid) for r in replay.robots], axis=1)
        self._done_us = -1

    def _prior(self, vid: int, groundtruth: np.ndarray) -> Block:
        """The launch prior: the Vicon pose at the start, perturbed within the datasheet's prior sigma."""
        spec = self.config.sensors
        sigma = np.array([spec.prior_sigma_m, spec.prior_sigma_m, spec.prior_heading_sigma_rad])
        pose = pose_at(groundtruth, np.array([self.start_s]))[0]
        if not np.all(np.isfinite(pose)):
            raise DataError(f"robot {self.robots[vid]} has no ground truth at the replay's start ({self.start_s:g} s)")
        rng = np.random.default_rng([self.config.world.seed, vid])
        row = np.concatenate([pose + rng.normal(0.0, sigma), np.diag(sigma**2).ravel()])
        return np.zeros(1, np.int64), row[None, :]

    def _truth_rows(self, groundtruth: np.ndarray, grid_us: np.ndarray) -> np.ndarray:
        """(k, 6) [x, y, theta, speed, yaw rate, height] on the grid; speed and yaw rate by central
        differences, height 0 (the robots drive on a floor)."""
        t = self.start_s + grid_us * 1e-6
        pose = pose_at(groundtruth, t)
        dt = 0.02
        ahead, behind = pose_at(groundtruth, t + dt), pose_at(groundtruth, t - dt)
        speed = np.hypot(*(ahead[:, :2] - behind[:, :2]).T) / (2 * dt)
        rate = wrap_angles(ahead[:, 2] - behind[:, 2]) / (2 * dt)
        rows = np.column_stack([pose, np.nan_to_num(speed), np.nan_to_num(rate), np.zeros(len(t))])
        rows[np.isnan(pose[:, 0])] = np.nan
        return rows

    def vehicle_ids(self) -> list[int]:
        return list(self.robots)

    def _true_pose(self, vid: int, t_us: int) -> np.ndarray:
        i = min(np.searchsorted(self._truth_stamps, t_us), len(self._truth_stamps) - 1)
        return self._truth[i, vid - 1, :3]

    def comm_jammed(self, t_us: int) -> tuple[int, ...]:
        return tuple(vid for vid in self.robots if self.faults.comm_jammed(t_us, self._true_pose(vid, t_us)))

    def _silenced(self, vid: int, topic: str, t_us: int) -> bool:
        return bool(self.faults.faults) and self.faults.silenced(vid, topic, t_us, self._true_pose(vid, t_us))

    def _comm_lost(self, vid: int, target: int, t_us: int) -> bool:
        """A sighting of a robot is useless when either end is comm-jammed then: the neighbour's
        broadcast it pairs with is lost (as the simulated world drops such ranging)."""
        if not self.faults.faults:
            return False
        jammed = self.comm_jammed(t_us)
        return vid in jammed or target in jammed

    def _add_relayed(self, feeds: dict[int, dict[str, tuple[np.ndarray, int, np.ndarray]]]) -> None:
        """The seen robots' ``seen`` blocks, numbered on from what each was sent before."""
        for vid, (stamps, rows) in relayed_sightings(feeds).items():
            sent = self._sent.get((vid, Topic.SEEN), 0)
            feeds.setdefault(vid, {})[Topic.SEEN] = (stamps, sent, rows)
            self._sent[vid, Topic.SEEN] = sent + len(stamps)

    def advance(self, until_us: int) -> ReplayOutput:
        """Everything recorded in (last advance, until_us]."""
        feeds = {}
        for vid, topics in self._streams.items():
            feeds[vid] = {}
            for topic, (stamps, rows) in topics.items():
                first = self._cursor[vid, topic]
                last = int(np.searchsorted(stamps, until_us, side="right"))
                self._cursor[vid, topic] = last
                if first == last:
                    continue
                keep = np.arange(first, last)
                if self.faults.faults:
                    keep = keep[
                        [
                            not self._silenced(vid, topic, int(stamps[i]))
                            and not (topic == Topic.RANGING and self._comm_lost(vid, int(rows[i, 0]), int(stamps[i])))
                            for i in keep
                        ]
                    ]
                if len(keep):
                    feeds[vid][topic] = (stamps[keep], self._sent[vid, topic], rows[keep])
                    self._sent[vid, topic] += len(keep)
        if self._relay:
            self._add_relayed(feeds)
        lo = int(np.searchsorted(self._truth_stamps, self._done_us, side="right"))
        hi = int(np.searchsorted(self._truth_stamps, until_us, side="right"))
        self._done_us = until_us
        return ReplayOutput(feeds, self._truth_stamps[lo:hi], self._truth[lo:hi])
