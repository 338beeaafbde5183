"""The AR-EKF-SLAM paper's three-dimensional back end: the 6 + 3n EKF (vehicle.models.slam3d) with the
adaptive observation range in 3-D distance, data association on the triangulated points
(vehicle.association, of dimension 3), and marginalisation of what leaves the range. Pure: no bus, no
clock; the experiments fly it, and ``ar-ekf-slam-3d`` (vehicle.estimators.ar_ekf_slam_3d) runs it in
a vehicle process.

Per camera frame (``frame``): the state is predicted to the frame (constant velocity); the landmarks
in the state farther than R from the camera are retired (marginalised out);
the frame's triangulated points z_i (body frame, covariance R_i from vehicle.vision.triangulation)
are associated with the landmarks in the state (the configured method, behind the chi-square gate),
the pairs fused one by one, and the unpaired points within R initialised as new landmarks (the
paper's g and its blocks; see Entry); then R follows the paper's state machine q1-q3
(ar_ekf_slam.next_radius) with n the landmarks in the local map; with ``regrow``, a local map of
fewer than n_min landmarks takes R out at once to the frame's points before the frame
(ar_ekf_slam.regrown_radius). A retired landmark seen again is
initialised anew (``reinit``, the 2-D estimator's default). A fixed range is R with q1-q3 off, and a
range of infinity is full EKF-SLAM.

Entry (``entry``). ``first``, the paper's: a point enters the map on the sighting that finds it within
R, initialised from that sighting. Deciding on a point's noisy depth and initialising it from the same
depth keeps the points measured short and makes their errors one-sided (docs/ar-slam.md). ``second``
(default) splits the two: the first sighting within R makes the point a candidate, the next sighting
of it (by id, or the nearest candidate within the gate) initialises it, whatever that sighting's own
depth; a candidate not seen again within a few frames is let go (the decision:
vehicle.estimators.ar_slam3d_entry).

Noise. A triangulated point's covariance worked out at its own pixels follows its own error (its depth
variance grows as depth^4), so a landmark fused from many sightings drifts short while its covariance
shrinks (docs/decisions/ar-slam3d-noise.md). Given ``noise_at``, a sighting of a landmark in the state
is fused with the covariance at the landmark's prediction before the frame; association and entry use
the sighting's own.

The rotation of each frame, R_wc (the camera's axes in the fixed frame), is given: the paper takes it
from visual odometry (R from E, cheirality) and does not estimate it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bus.config import ArSlamConfig
from bus.statistics import gate_threshold
from vehicle.association.methods import METHODS
from vehicle.association.problem import problem
from vehicle.estimators.ar_ekf_slam import next_radius, regrown_radius
from vehicle.estimators.ar_slam3d_entry import Candidate, Entry, Unpaired, entering
from vehicle.models import added_states, slam3d
from vehicle.models.kalman import gated_update

AMBIGUOUS = -2  # an assignment's mark for a point set aside (``unambiguous``)


@dataclass
class Ar3dBook:
    """What the back end keeps besides x and P: the range, and counts of what it did (landmarks retired,
    sightings fused, landmarks added, sightings gated out)."""

    radius_m: float
    retired: int = 0
    fused: int = 0
    added: int = 0
    gated_out: int = 0


class ArSlam3d:
    """The back end (module docstring): ``x`` = [p, v, X_1 ... X_n], ``P`` its covariance."""

    def __init__(
        self,
        x0: np.ndarray,
        P0: np.ndarray,
        *,
        spec: ArSlamConfig = ArSlamConfig(),
        omega_var: float | np.ndarray = 0.05,  # the velocity's white increment per step, m^2/s^2 (or (3,) per axis)
        association: str = "nn",
        adaptive: bool = True,
        gate_probability: float = 0.999,
        entry: Entry = "second",
        seed: int = 0,
        unambiguous: bool = False,
        regrow: bool = False,
    ) -> None:
        self.x, self.P = np.asarray(x0, float).copy(), np.asarray(P0, float).copy()
        self.regrow = regrow
        self.unambiguous = unambiguous
        self.spec, self.omega_var, self.adaptive = spec, omega_var, adaptive
        self.associate = METHODS[association]
        self.gate_probability = gate_probability
        self.gate = gate_threshold(3, gate_probability)
        self.book = Ar3dBook(spec.r0_m)
        self.rng = np.random.default_rng(seed)
        self.ids = np.zeros(0, np.int64)  # each state landmark's id where the frames are identified (else -1)
        self.entry = entry
        self.candidates: list[Candidate] = []
        self._shared: tuple | None = None  # while a frame's new landmarks enter: its shared errors' G, pixel R_z
        self.frames = 0

    def landmarks(self) -> np.ndarray:
        """The landmarks in the state (n, 3)."""
        return self.x[slam3d.HEAD :].reshape(-1, 3)

    def predict(self, dt: float, omega_var: float | np.ndarray | None = None) -> None:
        """The constant-velocity step of ``dt`` s with the velocity's white increment ``omega_var`` over
        it (m^2/s^2; None: the back end's per-frame ``omega_var``)."""
        increment = self.omega_var if omega_var is None else omega_var
        self.x, self.P = slam3d.predict(self.x, self.P, dt, increment)

    def position_fix(self, xy: np.ndarray, cov: np.ndarray, gate: float):
        """A horizontal position fix (a GNSS receiver's) xy (2,) m with covariance (2, 2): one gated
        update of the position's first two rows; the update's result."""
        H = np.zeros((2, len(self.x)))
        H[0, 0] = H[1, 1] = 1.0
        self.x, self.P, result = gated_update(self.x, self.P, xy - self.x[:2], H, cov, gate, columns=np.arange(2))
        return result

    def frame(
        self,
        z: np.ndarray,
        R_z: np.ndarray,
        rotation: np.ndarray,
        ids: np.ndarray | None = None,
        common: tuple[np.ndarray, np.ndarray] | None = None,
        noise_at: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        """One frame's triangulated points z (k, 3) with covariances R_z (k, 3, 3), camera rotation
        ``rotation`` (3, 3) (module docstring); the state must be predicted to the frame first.
        ``ids`` (k,): the points' landmark ids where the frame is identified (association by id,
        as a replay's identified sightings), else the configured association method. ``common``:
        errors the frame's points share (the rotation's, the baseline's), as G (k, 3, c), the
        innovation of each point per unit of each error, and their covariance (c, c); they are
        states while the frame's points are fused and new landmarks enter (so that they count once,
        and a new landmark keeps them as correlations), and marginalised after. ``noise_at(points)``:
        the covariances (m, 3, 3) the triangulation gives points (m, 3) of z's frame; a sighting of a
        landmark in the state is then fused with the noise at its prediction before the frame rather
        than at its own measurement, which follows the measurement's error (``Noise``)."""
        if self.regrow:  # an emptied local map reaches for the frame's points at once
            distances = np.linalg.norm(z, axis=1)
            self.book.radius_m = regrown_radius(self.book.radius_m, slam3d.landmarks(self.x), distances, self.spec)
        self._retire()
        n = slam3d.landmarks(self.x)
        G, shared = common if common is not None else (np.zeros((len(z), 3, 0)), np.zeros((0, 0)))
        first = len(self.x)  # the shared errors' first row while they are in the state
        self.x, self.P = np.append(self.x, np.zeros(len(shared))), np.pad(self.P, ((0, len(shared)), (0, len(shared))))
        self.P[first:, first:] = shared
        R_alone = R_z + np.einsum("nic,cd,njd->nij", G, shared, G)  # a point's noise with its share
        assignment = self._assign(n, z, R_alone, rotation, ids)
        paired = np.flatnonzero(assignment >= 0)
        R_fused = (
            R_z if noise_at is None else _noise_at_predictions(self.x[:first], assignment, rotation, R_z, noise_at)
        )
        for i in paired:
            j = int(assignment[i])
            h, H_j = slam3d.observe(self.x, j, rotation)
            H_j[:, first:] = G[i]
            columns = np.r_[: slam3d.POINT, slam3d.landmark_slice(j), first : len(self.x)]  # position, X_j, shared
            self.x, self.P, result = gated_update(self.x, self.P, z[i] - h, H_j, R_fused[i], self.gate, columns=columns)
            self.book.fused += int(result.accepted)
            self.book.gated_out += int(not result.accepted)
        self._shared = (G, R_z) if len(shared) else None  # new landmarks meet the shared errors
        self._enter(np.flatnonzero(assignment == -1), z, R_alone, rotation, ids)
        self._shared = None
        kept = len(self.x) - len(shared)
        self.x, self.P = self.x[:kept], self.P[:kept, :kept]  # the shared errors marginalised out
        if self.adaptive:
            self.book.radius_m = next_radius(self.book.radius_m, slam3d.landmarks(self.x), self.spec)

    def _assign(self, n: int, z: np.ndarray, R_z: np.ndarray, rotation: np.ndarray, ids) -> np.ndarray:
        """Which of the n landmarks each point z (k, 3) (noise R_z) is: by id where the frame is
        identified, else the configured method behind the gate (ambiguous pairings set aside when
        ``unambiguous``); -1: none."""
        if ids is not None:
            where = {int(ident): j for j, ident in enumerate(self.ids.tolist())}
            return np.array([where.get(int(ident), -1) for ident in ids], dtype=np.int64)
        if not (n and len(z)):
            return np.full(len(z), -1)
        predicted, H = zip(*(slam3d.observe(self.x, j, rotation) for j in range(n)))
        H = np.vstack(H)
        gated = problem(
            z, R_z, np.array(predicted), H @ self.P @ H.T, gate_probability=self.gate_probability, angles=()
        )
        assignment = self.associate(gated, self.rng)
        return _without_ambiguous(assignment, gated.candidates) if self.unambiguous else assignment

    def turn_velocity(self, angle_rad: float, angle_var: float) -> None:
        """The horizontal velocity turned by ``angle_rad`` about the vertical, that angle uncertain by
        ``angle_var`` (rad^2): v' = R_z(a) v, P' = T P T^T + var (d v'/d a)(d v'/d a)^T."""
        c, s = np.cos(angle_rad), np.sin(angle_rad)
        turn = np.array([[c, -s], [s, c]])
        self.x[3:5] = turn @ self.x[3:5]
        self.P[3:5, :] = turn @ self.P[3:5, :]
        self.P[:, 3:5] = self.P[:, 3:5] @ turn.T
        across = np.array([-self.x[4], self.x[3]])
        self.P[3:5, 3:5] += angle_var * np.outer(across, across)

    def relocalize(self, xy: np.ndarray, cov: np.ndarray, velocity_var: float) -> None:
        """Lost: the map dropped (its landmarks were placed from a pose that is wrong), the horizontal
        position put at ``xy`` (2,) m with covariance ``cov`` (2, 2) (an absolute fix's), the rest of
        the vehicle's state kept with its variances only, ``velocity_var`` (m^2/s^2) added on the
        horizontal velocity."""
        head = slam3d.HEAD
        self.x, self.P = self.x[:head].copy(), np.diag(np.diagonal(self.P)[:head])
        self.x[:2] = xy
        self.P[:2, :2] = cov
        self.P[[3, 4], [3, 4]] += velocity_var
        self.ids, self.candidates = self.ids[:0], []

    def _enter(self, unpaired: np.ndarray, z: np.ndarray, R_z: np.ndarray, rotation: np.ndarray, ids) -> None:
        """New landmarks from the unpaired points (module docstring, ``entry``; the decision:
        vehicle.estimators.ar_slam3d_entry)."""
        self.frames += 1
        placed = [self._in_the_map(z[i], R_z[i], rotation) for i in unpaired]
        points = Unpaired(
            index=np.asarray(unpaired, dtype=np.int64),
            xyz=np.array([xyz for xyz, _ in placed]).reshape(-1, 3),
            cov=np.array([cov for _, cov in placed]).reshape(-1, 3, 3),
            ident=np.full(len(unpaired), -1) if ids is None else np.asarray(ids)[unpaired].astype(np.int64),
            identified=ids is not None,
            within=np.linalg.norm(z[unpaired].reshape(-1, 3), axis=1) <= self.book.radius_m,
        )
        enter, self.candidates = entering(self.candidates, points, self.frames, self.gate, self.entry)
        for i, ident in enter.items():
            self._add(i, z[i], R_z[i], rotation, ident)

    def _in_the_map(self, z: np.ndarray, R_z: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.x[:3] + rotation @ z, self.P[:3, :3] + rotation @ R_z @ rotation.T

    def _add(self, i: int, z: np.ndarray, R_z: np.ndarray, rotation: np.ndarray, ident: int) -> None:
        """Point i of the frame, z (3,) with R_z (3, 3) its noise with its share of the frame's shared
        errors, enters the map. With shared errors (``frame``'s ``common``) it is placed from the state
        that still carries them: X = p + R (z - G_i c), so that the errors it shares with the frame's
        other points and with the pose stay correlations of P, not independent noise (the paper's
        P_new with grad g_X widened to those rows)."""
        if self._shared is None:
            self.x, self.P = slam3d.add_landmark(self.x, self.P, z, R_z, rotation)
        else:
            G, R_pixels = self._shared
            first = len(self.x) - G.shape[-1]  # the shared errors are the state's last rows
            self.x, self.P = _insert_point(self.x, self.P, first, z, R_pixels[i], -rotation @ G[i], rotation)
        self.ids = np.append(self.ids, ident)
        self.book.added += 1

    def _retire(self) -> None:
        """Landmarks farther than R from the camera leave the state (marginalised: a retired landmark
        seen again enters anew, so its marginal is not kept)."""
        far = np.flatnonzero(np.linalg.norm(self.landmarks() - self.x[:3], axis=1) > self.book.radius_m)
        if not len(far):
            return
        self.book.retired += len(far)
        drop = (slam3d.HEAD + slam3d.POINT * far[:, None] + np.arange(slam3d.POINT)).ravel().tolist()
        self.x, self.P = added_states.drop_states(self.x, self.P, drop)
        self.ids = np.delete(self.ids, far)


def _noise_at_predictions(
    x: np.ndarray, assignment: np.ndarray, rotation: np.ndarray, R_z: np.ndarray, noise_at: Callable
) -> np.ndarray:
    """The points' noise (k, 3, 3) to fuse with (``Noise``): for each point paired with landmark j of x
    (6 + 3n,) (``assignment`` (k,), -1: none), what ``noise_at`` gives at h = R^T (X_j - p); its own
    ``R_z`` for the rest, and where the prediction has none (behind a camera: NaN)."""
    paired = np.flatnonzero(assignment >= 0)
    if not len(paired):
        return R_z
    mapped = x[slam3d.HEAD :].reshape(-1, slam3d.POINT)[assignment[paired]]
    at_prediction = noise_at((mapped - x[: slam3d.POINT]) @ rotation)
    known = np.isfinite(at_prediction).all(axis=(1, 2))
    out = R_z.copy()
    out[paired[known]] = at_prediction[known]
    return out


def _without_ambiguous(assignment: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """The assignment (k,) with every point that another landmark's gate also admits, or whose
    landmark's gate admits another point, set aside (-2: neither fused nor entered): a pairing the
    gate cannot single out is the likeliest wrong one when the pose is uncertain. ``candidates``
    (k, m) bool: the individually compatible pairs."""
    out = assignment.copy()
    paired = np.flatnonzero(assignment >= 0)
    rivals = (candidates[paired].sum(axis=1) > 1) | (candidates[:, assignment[paired]].sum(axis=0) > 1)
    out[paired[rivals]] = AMBIGUOUS
    return out


def _insert_point(
    x: np.ndarray,
    P: np.ndarray,
    at: int,
    z: np.ndarray,
    R_z: np.ndarray,
    shared_jacobian: np.ndarray,
    rotation: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The state grown by the landmark X = p + R z seen at z (3,) with noise R_z (3, 3), inserted at
    row ``at`` before the shared errors' rows (from ``at`` on), X's Jacobian on which is
    ``shared_jacobian`` (3, len(x) - at)."""
    n = len(x)
    J = np.zeros((slam3d.POINT, n))
    J[:, : slam3d.POINT] = np.eye(slam3d.POINT)
    J[:, at:] = shared_jacobian
    cross = J @ P
    block = cross @ J.T + rotation @ R_z @ rotation.T
    keep = np.r_[:at, at + slam3d.POINT : n + slam3d.POINT]
    new = np.arange(at, at + slam3d.POINT)
    P_new = np.empty((n + slam3d.POINT, n + slam3d.POINT))
    P_new[np.ix_(keep, keep)] = P
    P_new[np.ix_(new, keep)] = cross
    P_new[np.ix_(keep, new)] = cross.T
    P_new[np.ix_(new, new)] = 0.5 * (block + block.T)
    return np.insert(x, at, x[: slam3d.POINT] + rotation @ z), P_new
