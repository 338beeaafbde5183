"""``ar-ekf-slam``: EKF-SLAM with an adaptive observation range (the AR-EKF-SLAM paper): ``ekf-slam``
whose state keeps only the landmarks inside a circle of radius R around the vehicle (the local map),
so the state, and with it the per-frame cost, stays bounded however large the map grows.

**The range** (paper, states q1-q3), once per camera frame, with n the landmarks in the local map:
n < n_min and R < R_max: grow R by dR (q1); n > n_max or R > R_max: shrink it by dR (q2); otherwise
keep it (q3). The paper's values are the defaults (R0 = 25 m, n_min = 8, n_max = 50, R_max = 35 m,
dR = 0.1 m): its camera saw tens of metres, ours about 8 x 8 m with a landmark per 3 x 3 m cell,
so the local map reaches n_max at about 12 m and R settles there (docs/ar-slam.md).

**Leaving the local map.** A landmark farther than R is marginalized out of the state (exact for a
Gaussian: its rows and columns dropped) and *retired* with its marginal (position, 2 x 2 covariance)
and its descriptor. **Coming back** (``reentry``):

- ``reinit`` (default): a retired landmark the camera sees again (its descriptor matched among the
  retired landmarks in view) is initialised as new from that sighting, the paper's g(x, z) with Gx
  and Gz; its old marginal is dropped. Sound: nothing is counted twice (Dissanayake et al. 2002).
- ``ci``: the same, then the old marginal fused into it by Covariance Intersection in the landmark's
  measurement space (Julier and Uhlmann 2007: the old estimate shares unknown errors with the
  current pose), the rest of the state following through its regression on the landmark.
- ``naive``: a retired landmark back within R is put back into the state with its old marginal
  and no cross-covariance. It double counts (the marginal and the current pose share the errors
  they had when it left) and makes the filter over-confident; kept to show that (tests).

Pure: no bus, no clock.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from bus.config import ArSlamConfig, SensorSpec, VehicleProcessConfig
from bus.statistics import gate_threshold
from vehicle.association import descriptors as matching
from vehicle.estimators.ekf_slam import build as build_ekf_slam
from vehicle.estimators.ekf_slam import config_arguments
from vehicle.estimators.filter import Filter
from vehicle.estimators.state import FilterState, frozen
from vehicle.estimators.vision_map import Reject, VisionSlamMap
from vehicle.models import added_states
from vehicle.models import landmarks as slam
from vehicle.models.cooperative import CooperativeRule, Correction, closed_form_weight
from vehicle.trust.neighbours import MonitorSpec

MAX_RETIRED = 100_000
REENTRY_GATE = gate_threshold(2, 0.999)  # a re-entered landmark against its old marginal
Reentry = Literal["reinit", "ci", "naive"]


def next_radius(radius_m: float, n: int, spec: ArSlamConfig) -> float:
    """The paper's range state machine: q1 grow, q2 shrink, q3 keep (module docstring)."""
    if n < spec.n_min and radius_m < spec.r_max_m:
        return min(radius_m + spec.dr_m, spec.r_max_m)
    if n > spec.n_max or radius_m > spec.r_max_m:
        return max(radius_m - spec.dr_m, spec.dr_m)
    return radius_m


def regrown_radius(radius_m: float, n: int, distances_m: np.ndarray, spec: ArSlamConfig) -> float:
    """q1 at once: a local map of fewer than n_min landmarks (``n``) takes R out to the n_min-th nearest
    of a frame's points (``distances_m`` (k,) m from the camera), at most R_max, instead of by the
    paper's dR a frame while the vehicle dead-reckons (docs/decisions/ar-slam3d-rendered.md); R as it
    is when the map holds enough or the frame has fewer than n_min points."""
    if n >= spec.n_min or len(distances_m) < spec.n_min:
        return radius_m
    reach = float(np.sort(distances_m)[spec.n_min - 1])
    return min(max(radius_m, reach), spec.r_max_m)


@dataclass
class RangeBook:
    """The range and the retired landmarks: positions (k, 2) m, marginal covariances (k, 2, 2) and
    descriptors (k, d), read-only arrays replaced by grown or cut copies."""

    radius_m: float
    xy: np.ndarray
    cov: np.ndarray
    ids: np.ndarray  # (k,) a replay's landmark ids, -1 for a camera's landmarks
    descriptors: np.ndarray | None = None
    managed_us: int = -1  # identified sightings: the stamp of the image last managed


class LocalMap:
    """The map policy of ``ar-ekf-slam`` (module docstring) for ``VisionSlamMap``."""

    capacity = 10**9  # the range keeps the state small; MAX_RETIRED bounds what leaves it

    def __init__(self, spec: ArSlamConfig) -> None:
        self.spec = spec

    def start(self) -> RangeBook:
        empty_ids = frozen(np.zeros(0, dtype=np.int64))
        return RangeBook(self.spec.r0_m, frozen(np.zeros((0, 2))), frozen(np.zeros((0, 2, 2))), empty_ids)

    def before_sighting(self, s: FilterState, the_map: VisionSlamMap, stamp_us: int) -> None:
        """Identified sightings (a replay): the range managed once per image (per stamp)."""
        book: RangeBook = s.landmarks.policy
        if stamp_us > book.managed_us:
            book.managed_us = stamp_us
            self.before_frame(s, the_map)

    def take_retired(self, s: FilterState, ident: int) -> tuple[np.ndarray, np.ndarray] | None:
        """The retired marginal of identified landmark ``ident`` (forgotten: it re-enters), or None."""
        book: RangeBook = s.landmarks.policy
        rows = np.flatnonzero(book.ids == ident)
        if not len(rows):
            return None
        retired = (book.xy[rows[0]].copy(), book.cov[rows[0]].copy())
        self._forget(book, rows[:1])
        return retired

    def reentered(self, s: FilterState, k: int, retired: tuple[np.ndarray, np.ndarray]) -> None:
        """A landmark re-initialised at state index ``k`` from a sighting: ``ci`` fuses its old marginal."""
        if self.spec.reentry == "ci":
            fuse_old_marginal(s, k, *retired)

    def occupied(self, s: FilterState) -> np.ndarray:
        return s.landmarks.policy.xy

    def before_frame(self, s: FilterState, the_map: VisionSlamMap) -> None:
        """Adapt R to the local map's size, retire the landmarks beyond it, and (``naive`` only) put
        back retired ones within it."""
        book: RangeBook = s.landmarks.policy
        book.radius_m = next_radius(book.radius_m, s.counters.landmarks, self.spec)
        mapped = the_map.landmarks_xy(s)
        far = np.flatnonzero(np.hypot(*(mapped - s.x[:2]).T) > book.radius_m) if len(mapped) else []
        if len(far):
            self._retire(s, the_map, far)
        if self.spec.reentry == "naive" and len(book.xy):
            near = np.flatnonzero(np.hypot(*(book.xy - s.x[:2]).T) <= book.radius_m)
            if len(near):
                self._put_back(s, the_map, near)

    def _retire(self, s: FilterState, the_map: VisionSlamMap, rows: np.ndarray) -> None:
        """Marginalize landmarks ``rows`` of the local map out of the state into the retired book."""
        head, local, book = the_map.head_dim, s.landmarks, s.landmarks.policy
        i = head + 2 * rows
        cov = np.empty((len(rows), 2, 2))
        cov[:, 0, 0], cov[:, 1, 1] = s.P[i, i], s.P[i + 1, i + 1]
        cov[:, 0, 1] = cov[:, 1, 0] = s.P[i, i + 1]
        xy = s.x[head:].reshape(-1, 2)[rows]
        ident_of = {j: ident for ident, j in local.index_of.items()}
        ids = np.array([ident_of.get(int(j), -1) for j in rows], dtype=np.int64)
        s.x, s.P = added_states.drop_states(s.x, s.P, np.concatenate([i, i + 1]).tolist())
        s.P = np.ascontiguousarray(s.P)  # the in-place updates need it C-contiguous
        keep = _without(s.counters.landmarks, rows)
        descriptors = None if local.descriptors is None else local.descriptors[rows]
        local.descriptors = None if local.descriptors is None else frozen(local.descriptors[keep])
        local.first_xy = None if local.first_xy is None else frozen(local.first_xy[keep])
        renumber = {int(old): new for new, old in enumerate(keep)}
        local.index_of = {ident: renumber[j] for ident, j in local.index_of.items() if j in renumber}
        s.counters.landmarks = len(keep)
        if len(book.xy) + len(rows) <= MAX_RETIRED:
            book.xy = frozen(np.vstack([book.xy, xy]))
            book.cov = frozen(np.concatenate([book.cov, cov]))
            book.ids = frozen(np.concatenate([book.ids, ids]))
            if descriptors is not None:
                grown = descriptors if book.descriptors is None else np.vstack([book.descriptors, descriptors])
                book.descriptors = frozen(np.ascontiguousarray(grown))

    def _forget(self, book: RangeBook, rows: np.ndarray | list[int]) -> None:
        keep = _without(len(book.xy), rows)
        book.xy, book.cov, book.ids = frozen(book.xy[keep]), frozen(book.cov[keep]), frozen(book.ids[keep])
        book.descriptors = None if book.descriptors is None else frozen(book.descriptors[keep])

    def _put_back(self, s: FilterState, the_map: VisionSlamMap, rows: np.ndarray) -> None:
        """``naive``: retired landmarks back into the state with their old marginals, uncorrelated."""
        book = s.landmarks.policy
        P_new = np.zeros((2 * len(rows), 2 * len(rows)))
        for k, r in enumerate(rows):
            P_new[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = book.cov[r]
        s.x, s.P = added_states.insert_states(s.x, s.P, len(s.x), book.xy[rows].ravel(), P_new)
        descriptors = None if book.descriptors is None else book.descriptors[rows]
        first_index = s.counters.landmarks
        the_map.grow_book(s, descriptors, len(rows))
        local = s.landmarks
        identified = {int(book.ids[r]): first_index + k for k, r in enumerate(rows) if book.ids[r] >= 0}
        local.index_of = {**local.index_of, **identified}
        self._forget(book, rows)

    def reenter(
        self, s: FilterState, the_map: VisionSlamMap, found, z, R, matched: set[int], half_extent_m: float
    ) -> set[int]:
        """Retired landmarks the frame sees again (descriptor match among those in view), re-entered
        by the rule; returns the keypoints used."""
        book: RangeBook = s.landmarks.policy
        if self.spec.reentry == "naive" or book.descriptors is None or not len(book.xy):
            return set()
        visible = matching.in_view(book.xy, s.x[:3], half_extent_m)
        free = [i for i in range(len(z)) if i not in matched]
        if not len(visible) or not free:
            return set()
        pairs = matching.match(found.descriptors[free], book.descriptors[visible], the_map.norm)
        pairs = [(free[i], int(visible[row])) for i, row in pairs]
        for i, r in pairs:
            s.x, s.P = slam.add_landmarks(s.x, s.P, z[i][None, :], R[i])
            the_map.grow_book(s, book.descriptors[r][None, :], 1)
            if self.spec.reentry == "ci":
                fuse_old_marginal(s, len(s.x) - 2, book.xy[r], book.cov[r])
        if pairs:
            self._forget(book, [r for _, r in pairs])
        return {i for i, _ in pairs}


def _without(n: int, rows: np.ndarray | list[int]) -> np.ndarray:
    """0..n-1 without ``rows``, in order."""
    mask = np.ones(n, dtype=bool)
    mask[rows] = False
    return np.flatnonzero(mask)


def fuse_old_marginal(s: FilterState, k: int, old_xy: np.ndarray, old_cov: np.ndarray) -> bool:
    """Covariance Intersection of the landmark at state index ``k`` with its old marginal (old_xy (2,),
    old_cov (2, 2)), in the landmark's space, the rest of the state following (in place); behind a
    chi-square gate on their difference (a false descriptor match must not close a loop). True when
    fused."""
    M = s.P[k : k + 2, k : k + 2].copy()
    gap = old_xy - s.x[k : k + 2]
    if not float(gap @ np.linalg.solve(M + old_cov, gap)) <= REENTRY_GATE:
        return False
    w = closed_form_weight(M, old_cov)
    if w >= 1.0:
        return False
    own = w * np.linalg.inv(M) if w > 0.0 else np.zeros((2, 2))
    other = (1.0 - w) * np.linalg.inv(old_cov)
    M_new = np.linalg.inv(own + other)
    dz = M_new @ (own @ s.x[k : k + 2] + other @ old_xy) - s.x[k : k + 2]
    cov_xz = s.P[:, k : k + 2].copy()
    correction = Correction(dz, M, 0.5 * (M_new + M_new.T), cov_xz[:3], w, cov_xz)
    slam.apply_correction_in_place(s.x, s.P, correction)
    return True


def retired_map(s: FilterState) -> tuple[np.ndarray, np.ndarray]:
    """The retired landmarks: positions (k, 2) and marginal covariances (k, 2, 2)."""
    book = s.landmarks.policy if s.landmarks is not None else None
    if book is None:
        return np.zeros((0, 2)), np.zeros((0, 2, 2))
    return book.xy, book.cov


def build(
    *,
    vehicle_id: int,
    spec: SensorSpec,
    gate_probability: float,
    ar: ArSlamConfig = ArSlamConfig(),
    detector: str = "sift",
    reject: Reject | None = None,
    cooperative: CooperativeRule = CooperativeRule(),
    adaptive_window: int = 0,
    front_end_results: dict | None = None,
    monitor: MonitorSpec | None = MonitorSpec(),
    association: str = "descriptor",
) -> Filter:
    """The AR-EKF-SLAM filter of vehicle ``vehicle_id``: ``ekf-slam`` with the local-map policy."""
    f = build_ekf_slam(
        vehicle_id=vehicle_id,
        spec=spec,
        gate_probability=gate_probability,
        detector=detector,
        reject=reject,
        cooperative=cooperative,
        adaptive_window=adaptive_window,
        front_end_results=front_end_results,
        monitor=monitor,
        policy=LocalMap(ar),
        association=association,
    )
    f.name = "ar-ekf-slam"
    return f


def from_config(config: VehicleProcessConfig, vehicle_id: int, *, reject: Reject | None = None) -> Filter:
    """:func:`build` from a vehicle's configuration (its range settings are ``vehicle.ar``)."""
    return build(**config_arguments(config, vehicle_id, reject), ar=config.vehicle.ar)
