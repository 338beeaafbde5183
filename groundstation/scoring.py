"""Scores state estimates against truth interpolated at their timestamps (pure, no bus).

Errors are in the horizontal plane; NEES is over the pose [x, y, yaw] with the estimate's own
covariance (3 degrees of freedom), so its mean should be 3 for a consistent estimator. A vehicle that
estimates its height (a UAV over relief: bus.odometry_content.altitude_of) is scored on it too, apart:
its error against the truth's height above the launch point and its NEES of 1 degree of freedom.
"""

from __future__ import annotations

import heapq
import itertools
import logging
import math
from dataclasses import dataclass, field

import numpy as np

from bus import feed, statistics
from bus.angles import wrap_angle as wrap
from bus.consistency import ConsistencyTally
from bus.mavlink_codec import StateEstimate, pose_of
from bus.odometry_content import NOT_ESTIMATED_VAR, POSE_INDEX
from bus.once import computed_once, known
from groundstation.truth_track import TruthTrack

log = logging.getLogger("swarmloc.groundstation")
TRUTH_COLUMNS = [0, 1, 2, 5]  # of a truth batch's rows (bus.feed.TruthBatch): x, y, theta, height
MAX_PENDING = 500_000  # estimates waiting for the watermark; beyond, they are counted and dropped


@dataclass(frozen=True)
class Score:
    vehicle_id: int
    stamp_us: int
    error_m: np.ndarray  # (3,) x, y (m) and yaw (rad) error: estimate - truth
    pose_covariance: np.ndarray  # (3, 3) the estimate's covariance of [x, y, yaw] (m^2, m rad, rad^2)
    nees: float
    reset_counter: int
    estimate: StateEstimate
    truth_pose: np.ndarray  # (3,)
    altitude_error_m: float = math.nan  # estimate - truth of the height above the launch point (NaN: not estimated)
    altitude_nees: float = math.nan  # its NEES, 1 dof (NaN: not estimated)

    # read by the run directory, the recording and the tallies (three or four times a score): worked
    # out once (kept in the frozen dataclass's __dict__: bus.once)
    @computed_once
    def sigma(self) -> np.ndarray:
        """(3,) standard deviations of x, y (m) and yaw (rad)."""
        return np.sqrt(np.diag(self.pose_covariance))

    @computed_once
    def position_error_m(self) -> float:
        return float(np.hypot(self.error_m[0], self.error_m[1]))

    @property
    def altitude_sigma_m(self) -> float:
        """The height's standard deviation (m): ODOMETRY z's (NaN where no height is estimated)."""
        return math.nan if math.isnan(self.altitude_nees) else math.sqrt(self.estimate.pose_covariance[2, 2].item())


@dataclass
class Tally:
    """Running per-vehicle totals."""

    samples: int = 0
    sum_sq_position_m2: float = 0.0
    max_position_error_m: float = 0.0
    sum_nees: float = 0.0
    nees_inside: int = 0
    consistency: ConsistencyTally = field(default_factory=ConsistencyTally)  # block ANEES, tail shares
    altitude: AltitudeTally | None = None  # where the vehicle estimates its height

    def add(self, score: Score, bounds: tuple[float, float]) -> None:
        t_s = score.stamp_us * 1e-6
        self.add_sample(t_s, score.position_error_m, score.nees, bounds)
        if not math.isnan(score.altitude_nees):
            self.add_altitude(t_s, score.altitude_error_m, score.altitude_nees)

    def add_sample(self, t_s: float, error_m: float, nees: float, bounds: tuple[float, float]) -> None:
        """One score of the planar pose: its position error (m) and NEES (3 dof) at ``t_s`` (s)."""
        self.samples += 1
        self.sum_sq_position_m2 += error_m * error_m
        self.max_position_error_m = max(self.max_position_error_m, error_m)
        self.sum_nees += nees
        self.nees_inside += int(bounds[0] <= nees <= bounds[1])
        self.consistency.add(t_s, nees)

    def add_altitude(self, t_s: float, error_m: float, nees: float) -> None:
        """One score of the height: its error (m, signed) and NEES (1 dof) at ``t_s`` (s)."""
        if self.altitude is None:
            self.altitude = AltitudeTally()
        self.altitude.add(t_s, error_m, nees)


@dataclass
class AltitudeTally:
    """Running totals of a vehicle's height scores: samples, squared and largest error (m^2, m), the
    NEES's sum and its consistency (1 dof)."""

    samples: int = 0
    sum_sq_m2: float = 0.0
    max_error_m: float = 0.0
    sum_nees: float = 0.0
    consistency: ConsistencyTally = field(default_factory=lambda: ConsistencyTally(dof=1))

    def add(self, t_s: float, error_m: float, nees: float) -> None:
        err = abs(error_m)
        self.samples += 1
        self.sum_sq_m2 += err * err
        self.max_error_m = max(self.max_error_m, err)
        self.sum_nees += nees
        self.consistency.add(t_s, nees)


def score(est: StateEstimate, truth: np.ndarray) -> Score:
    """``est`` scored against ``truth`` (4,) [x, y, theta, height] or (3,) (no height known)."""
    planar = pose_of(est)
    cov = planar.pose_cov
    error = statistics.pose_error(planar.pose, truth)
    height = planar.altitude
    altitude_error = math.nan if height is None or len(truth) < 4 else height.height_m - float(truth[3])
    return Score(
        est.vehicle_id,
        est.time_usec,
        error,
        cov,
        statistics.nees(error, cov),
        est.reset_counter,
        est,
        _planar(truth),
        altitude_error,
        math.nan if height is None else altitude_error**2 / height.var,  # NaN where no height is known
    )


def score_all(ests: list[StateEstimate], truth_poses: list[np.ndarray]) -> list[Score | None]:
    """``score`` of each estimate against its truth (4,) (or (3,)), the poses, errors and NEES worked out
    for all at once (one solve over the stacked covariances: LAPACK's same solve of each, so each
    score is ``score``'s to the bit). None where a covariance is singular."""
    if not ests:
        return []
    poses = np.array([(e.position_m[0], e.position_m[1], e.yaw_rad) for e in ests])  # (n, 3)
    full = np.stack([e.pose_covariance for e in ests])  # (n, 6, 6)
    covs = full[:, POSE_INDEX][:, :, POSE_INDEX]  # (n, 3, 3)
    truths = np.array(truth_poses)  # (n, 4), or (n, 3) with no height
    truths = truths if truths.shape[1] == 4 else np.column_stack([truths, np.full(len(truths), np.nan)])
    errors = poses - truths[:, :3]
    for row in errors:
        row[2] = wrap(row[2])  # pose_error's wrap, as it wraps one
    try:
        solved = np.linalg.solve(covs, errors[:, :, None])[:, :, 0]  # (n, 3)
    except np.linalg.LinAlgError:  # one singular covariance: each on its own
        return [_score_or_none(e, t) for e, t in zip(ests, truth_poses, strict=True)]
    height_var = full[:, 2, 2]
    estimated = height_var > NOT_ESTIMATED_VAR  # (bus.odometry_content.altitude_of)
    height_error = np.where(estimated, -np.array([e.position_m[2] for e in ests]) - truths[:, 3], np.nan)
    height_nees = np.where(estimated, height_error**2 / np.where(estimated, height_var, 1.0), np.nan)
    scores = [
        Score(
            e.vehicle_id,
            e.time_usec,
            errors[i],
            covs[i],
            float(errors[i] @ solved[i]),
            e.reset_counter,
            e,
            _planar(t),
            float(height_error[i]),
            float(height_nees[i]),
        )
        for i, (e, t) in enumerate(zip(ests, truth_poses, strict=True))
    ]
    # the properties every score is read for, worked out for all at once (the same values: sqrt and
    # hypot are elementwise): kept where computed_once keeps them
    sigmas = np.sqrt(np.diagonal(covs, axis1=1, axis2=2))
    for s, sigma, position_error_m in zip(scores, sigmas, np.hypot(errors[:, 0], errors[:, 1]).tolist()):
        known(s, sigma=sigma, position_error_m=position_error_m)
    return scores


def _planar(truth: np.ndarray) -> np.ndarray:
    """The pose [x, y, theta] (3,) of a truth (4,) with its height, or the truth (3,) itself."""
    return truth[:3] if len(truth) > 3 else truth


def _score_or_none(est: StateEstimate, truth_pose: np.ndarray) -> Score | None:
    try:
        return score(est, truth_pose)
    except np.linalg.LinAlgError:  # the intake rejects degenerate covariances; never fatal here
        return None


@dataclass
class Scorer:
    """Holds estimates until the watermark passes them, then scores them in (stamp, vehicle) order."""

    truth: dict[int, TruthTrack] = field(default_factory=dict)
    pending: list[tuple[int, int, int, StateEstimate]] = field(default_factory=list)  # heap
    tallies: dict[int, Tally] = field(default_factory=dict)
    unscored: int = 0
    in_truth_gaps: int = 0  # estimates where a replayed data set has no truth (not scored)
    duplicates: int = 0
    late: int = 0
    dropped_full: int = 0
    last_scored_us: dict[int, int] = field(default_factory=dict)
    _seen: set[tuple[int, int]] = field(default_factory=set)
    _order: itertools.count = field(default_factory=itertools.count)
    # two-sided 95% chi-square bounds for one NEES sample
    bounds: tuple[float, float] = field(default_factory=lambda: statistics.chi2_band(statistics.POSE_NEES_DOF))

    def add_truth(self, vehicle_id: int, stamp_us: int, pose: np.ndarray) -> None:
        """One truth sample of a vehicle: pose [x, y, theta] (3,) or with its height (4,) (else unknown)."""
        if len(pose) == 3:
            pose = np.append(pose, math.nan)
        track = self.truth.get(vehicle_id)
        if track is None:
            track = self.truth[vehicle_id] = TruthTrack()
        track.add(stamp_us, pose)

    def add_truth_batch(self, batch: feed.TruthBatch) -> int:
        """Every vehicle's truth of a tick's batch (bus.feed.TruthBatch); the newest stamp (-1: none)."""
        ids = batch.vehicle_ids.tolist()
        rows = batch.rows[:, :, TRUTH_COLUMNS]
        for k, stamp in enumerate(batch.stamps_us.tolist()):
            for n, vid in enumerate(ids):
                self.add_truth(vid, stamp, rows[k, n])
        return int(batch.stamps_us[-1]) if len(batch.stamps_us) else -1

    def add_estimate(self, est: StateEstimate) -> bool:
        """Queue an estimate for scoring; a second copy (same vehicle and stamp) is counted and
        ignored, and so is one older than what was already scored for its vehicle. False when the
        pending buffer is full (counted)."""
        ident = (est.vehicle_id, est.time_usec)
        if ident in self._seen:
            self.duplicates += 1
        elif est.time_usec <= self.last_scored_us.get(est.vehicle_id, -1):
            self.late += 1
        elif len(self.pending) >= MAX_PENDING:
            self.dropped_full += 1
            return False
        else:
            self._seen.add(ident)
            heapq.heappush(self.pending, (est.time_usec, est.vehicle_id, next(self._order), est))
        return True

    def release(self, watermark_us: float) -> list[Score]:
        """Score every pending estimate stamped <= watermark_us, in (stamp, vehicle) order."""
        ests, truth_poses = [], []
        while self.pending and self.pending[0][0] <= watermark_us:
            est = heapq.heappop(self.pending)[3]
            track = self.truth.get(est.vehicle_id)
            if track is None or not track.covers(est.time_usec):
                self.unscored += 1
                log.warning(
                    "no truth for vehicle %d at %d us (truth covers %s); estimate not scored",
                    est.vehicle_id,
                    est.time_usec,
                    f"{track.stamps[0]}..{track.stamps[-1]}" if track and track.stamps else "nothing",
                )
                continue
            if track.in_gap(est.time_usec):
                self.in_truth_gaps += 1
                continue
            ests.append(est)
            truth_poses.append(track.at(est.time_usec))
        scores = []
        for result in score_all(ests, truth_poses):
            if result is None:
                self.unscored += 1
                continue
            tally = self.tallies.get(result.vehicle_id)
            if tally is None:
                tally = self.tallies[result.vehicle_id] = Tally()
            tally.add(result, self.bounds)
            self.last_scored_us[result.vehicle_id] = result.stamp_us
            scores.append(result)
        if watermark_us != float("inf"):
            for track in self.truth.values():
                track.forget_before(int(watermark_us) - 1_000_000)
            if len(self._seen) > 50_000:
                self._seen = {k for k in self._seen if k[1] >= watermark_us - 10_000_000}
        return scores
