"""What an ODOMETRY says: the estimate it carries (``StateEstimate``, or ``NoEstimate``), the checks
its contents must pass, and where a planar ``bus.estimate.PoseEstimate`` [x, y, yaw] sits in it: at
rows and columns [0, 1, 5] of the 6 x 6 pose covariance (local NED, z = -altitude, roll and pitch
level and not estimated), its speed and yaw rate at [0] and [5] of the velocity covariance
(``odometry_of`` / ``pose_of``). ``planar_estimate_of`` and ``planar_fields`` go between a
PoseEstimate and ODOMETRY's wire fields (bus.odometry_wire) directly, to the same values. A vehicle
that estimates its height (``PoseEstimate.altitude``) puts it at z (above its launch point) with its
variance and covariances at row 2; one that flies level claims z known to ``NOT_ESTIMATED_VAR``
(``altitude_of`` tells them apart). Pure; bus.mavlink_codec frames, signs and authenticates."""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass

import numpy as np
from pymavlink.dialects.v20 import common as mavlink2

from bus import odometry_wire as ow
from bus.errors import MavlinkRejected
from bus.estimate import Altitude, PoseEstimate

MAX_POSITION_M = 1e7
MAX_VARIANCE = 1e8  # m^2, rad^2: beyond this an estimate carries no information
POSE_INDEX = np.array([0, 1, 5])  # x, y, yaw in ODOMETRY's pose covariance
NOT_ESTIMATED_VAR = 1e-6  # z, roll, pitch (constant altitude, level flight) and the lateral velocities
_UPPER = np.triu_indices(6)
_LOCAL_NED, _BODY_FRD = mavlink2.MAV_FRAME_LOCAL_NED, mavlink2.MAV_FRAME_BODY_FRD  # ODOMETRY's frames
_VARIANCES = operator.itemgetter(0, 6, 11, 15, 18, 20)  # the variances' places in the 21-float upper triangle


def _symmetric_index() -> np.ndarray:
    """(6, 6) index into the 21-float upper triangle that rebuilds the full symmetric matrix."""
    index = np.zeros((6, 6), dtype=np.intp)
    index[_UPPER] = np.arange(21)
    return np.maximum(index, index.T)


_SYMMETRIC_INDEX = _symmetric_index()
_POSE_BLOCK = np.ix_(POSE_INDEX, POSE_INDEX)


@dataclass(frozen=True)
class StateEstimate:
    """One vehicle's state estimate as carried by ODOMETRY, in local NED.

    position_m (3,), velocity_mps (3,) in the body frame, covariances (6, 6) over
    [x, y, z, roll, pitch, yaw] and [vx, vy, vz, rollrate, pitchrate, yawrate].
    """

    vehicle_id: int
    time_usec: int
    position_m: np.ndarray
    yaw_rad: float
    velocity_mps: np.ndarray
    yaw_rate_radps: float
    pose_covariance: np.ndarray
    velocity_covariance: np.ndarray
    reset_counter: int = 0
    estimator_type: int = mavlink2.MAV_ESTIMATOR_TYPE_GPS_INS


@dataclass(frozen=True)
class NoEstimate:
    """An ODOMETRY whose pose covariance starts with NaN: in MAVLink's words the covariance, and so the
    estimate, is unknown. A vehicle that has no estimate yet still broadcasts one at each V2V epoch,
    so its neighbours know it has passed ``time_usec`` (lockstep waits on that)."""

    vehicle_id: int
    time_usec: int


def odometry_of(estimate: PoseEstimate, *, altitude_m: float, reset_counter: int) -> StateEstimate:
    """ODOMETRY's contents for a planar estimate flown at ``altitude_m``: NED position (x, y, -altitude),
    body-frame velocity (speed, 0, 0), the pose covariance at [0, 1, 5] of the 6 x 6 with the
    not-estimated axes at ``NOT_ESTIMATED_VAR``; z and row 2 the estimate's own altitude where it has
    one."""
    pose_cov = np.diag([0.0, 0.0, NOT_ESTIMATED_VAR, NOT_ESTIMATED_VAR, NOT_ESTIMATED_VAR, 0.0])
    pose_cov[_POSE_BLOCK] = estimate.pose_cov
    z = -altitude_m
    if estimate.altitude is not None:  # NED: z = -height, so its covariances change sign
        z = -estimate.altitude.height_m
        pose_cov[2, 2] = estimate.altitude.var
        pose_cov[0, 2] = pose_cov[2, 0] = -estimate.altitude.cov_xy[0]
        pose_cov[1, 2] = pose_cov[2, 1] = -estimate.altitude.cov_xy[1]
    vel_cov = np.diag(
        [
            estimate.speed_var,
            NOT_ESTIMATED_VAR,
            NOT_ESTIMATED_VAR,
            NOT_ESTIMATED_VAR,
            NOT_ESTIMATED_VAR,
            estimate.yaw_rate_var,
        ]
    )
    x, y, yaw = estimate.pose
    return StateEstimate(
        vehicle_id=estimate.vehicle_id,
        time_usec=estimate.stamp_us,
        position_m=np.array([x, y, z]),
        yaw_rad=float(yaw),
        velocity_mps=np.array([estimate.speed_mps, 0.0, 0.0]),
        yaw_rate_radps=estimate.yaw_rate_radps,
        pose_covariance=pose_cov,
        velocity_covariance=vel_cov,
        reset_counter=reset_counter,
    )


def pose_of(est: StateEstimate) -> PoseEstimate:
    """The planar estimate an ODOMETRY carries (the inverse of :func:`odometry_of` on x, y, yaw, and on
    the altitude where it has one)."""
    return PoseEstimate(
        vehicle_id=est.vehicle_id,
        stamp_us=est.time_usec,
        pose=np.array([est.position_m[0], est.position_m[1], est.yaw_rad]),
        pose_cov=est.pose_covariance[_POSE_BLOCK],
        speed_mps=float(est.velocity_mps[0]),
        speed_var=float(est.velocity_covariance[0, 0]),
        yaw_rate_radps=est.yaw_rate_radps,
        yaw_rate_var=float(est.velocity_covariance[5, 5]),
        altitude=altitude_of(est),
    )


def estimate_of(sysid: int, fields: tuple) -> StateEstimate | NoEstimate:
    """The estimate an ODOMETRY frame of ``sysid`` carries, from its fields in wire order
    (bus.odometry_wire), or MavlinkRejected."""
    if math.isnan(fields[ow.POSE_COVARIANCE][0]):
        return NoEstimate(sysid, fields[ow.TIME_USEC])
    _check_fields(sysid, fields)
    x, y, z, q = fields[ow.X], fields[ow.Y], fields[ow.Z], fields[ow.Q]
    pose_upper, velocity_upper = fields[ow.POSE_COVARIANCE], fields[ow.VELOCITY_COVARIANCE]
    pose_cov = _full_covariance(pose_upper)
    _check_pose_covariance(sysid, pose_cov[_POSE_BLOCK])
    w, _, _, qz = q
    return StateEstimate(
        vehicle_id=sysid,
        time_usec=fields[ow.TIME_USEC],
        position_m=np.array([x, y, z]),
        yaw_rad=2.0 * math.atan2(qz, w),
        velocity_mps=np.array([fields[ow.VX], fields[ow.VY], fields[ow.VZ]]),
        yaw_rate_radps=float(fields[ow.YAWSPEED]),
        pose_covariance=pose_cov,
        velocity_covariance=_full_covariance(velocity_upper),
        reset_counter=fields[ow.RESET_COUNTER],
        estimator_type=fields[ow.ESTIMATOR_TYPE],
    )


def altitude_of(est: StateEstimate) -> Altitude | None:
    """The height above its launch point an estimate carries with its variance and covariances (m,
    m^2), or None where the vehicle flies level (z's variance ``NOT_ESTIMATED_VAR`` or less)."""
    cov = est.pose_covariance
    if not cov[2, 2] > NOT_ESTIMATED_VAR:
        return None
    return Altitude(-float(est.position_m[2]), float(cov[2, 2]), (-float(cov[0, 2]), -float(cov[1, 2])))


def _check_fields(sysid: int, fields: tuple) -> None:
    """MavlinkRejected unless every value is finite, every variance non-negative, the position sane
    and the attitude a yaw."""
    x, y, z, q = fields[ow.X], fields[ow.Y], fields[ow.Z], fields[ow.Q]
    pose_upper, velocity_upper = fields[ow.POSE_COVARIANCE], fields[ow.VELOCITY_COVARIANCE]
    values = (x, y, z, *q, fields[ow.VX], fields[ow.VY], fields[ow.VZ], fields[ow.YAWSPEED], *pose_upper)
    if not all(map(math.isfinite, values + velocity_upper)):
        raise MavlinkRejected("degenerate", f"ODOMETRY from sysid {sysid} has non-finite fields")
    if min(_VARIANCES(pose_upper)) < 0 or min(_VARIANCES(velocity_upper)) < 0:  # all finite by now
        raise MavlinkRejected("degenerate", f"ODOMETRY from sysid {sysid} has negative variances")
    if max(abs(x), abs(y), abs(z)) > MAX_POSITION_M or abs(q[0]) + abs(q[3]) < 1e-6:
        raise MavlinkRejected("degenerate", f"ODOMETRY from sysid {sysid} has an absurd position or attitude")


def _check_pose_covariance(sysid: int, pose_cov: np.ndarray) -> None:
    """MavlinkRejected unless the [x, y, yaw] covariance (3, 3) is usable."""
    if not _usable_covariance(pose_cov):
        raise MavlinkRejected(
            "degenerate", f"ODOMETRY from sysid {sysid}: [x, y, yaw] covariance is zero, singular, indefinite or huge"
        )


def planar_estimate_of(sysid: int, fields: tuple) -> PoseEstimate | NoEstimate:
    """``pose_of(estimate_of(sysid, fields))`` without the 6 x 6 matrices in between: the same checks,
    refusals and values (a vehicle reads its neighbours' broadcasts so, some 20 a second)."""
    pose_upper, velocity_upper = fields[ow.POSE_COVARIANCE], fields[ow.VELOCITY_COVARIANCE]
    if math.isnan(pose_upper[0]):
        return NoEstimate(sysid, fields[ow.TIME_USEC])
    _check_fields(sysid, fields)
    u = pose_upper  # [x, y, yaw] sit at rows and columns 0, 1, 5: upper-triangle places 0, 1, 5, 6, 10, 20
    pose_cov = np.array([[u[0], u[1], u[5]], [u[1], u[6], u[10]], [u[5], u[10], u[20]]])
    _check_pose_covariance(sysid, pose_cov)
    w, _, _, qz = fields[ow.Q]
    return PoseEstimate(
        vehicle_id=sysid,
        stamp_us=fields[ow.TIME_USEC],
        pose=np.array([fields[ow.X], fields[ow.Y], 2.0 * math.atan2(qz, w)]),
        pose_cov=pose_cov,
        speed_mps=float(fields[ow.VX]),
        speed_var=float(velocity_upper[0]),
        yaw_rate_radps=float(fields[ow.YAWSPEED]),
        yaw_rate_var=float(velocity_upper[20]),
        altitude=Altitude(-fields[ow.Z], u[11], (-u[2], -u[7])) if u[11] > NOT_ESTIMATED_VAR else None,
    )


def planar_fields(estimate: PoseEstimate, *, altitude_m: float, reset_counter: int) -> tuple:
    """The wire fields (bus.odometry_wire) of ``odometry_of(estimate, ...)`` as ``MavlinkEncoder``
    packs them, without the 6 x 6 matrices in between (every vehicle sends some 10 a second)."""
    (c00, c01, c02), (_, c11, c12), (_, _, c22) = estimate.pose_cov.tolist()
    x, y, yaw = estimate.pose.tolist()
    half = 0.5 * yaw
    ne = NOT_ESTIMATED_VAR
    # the upper triangles row by row: [x, y, z, roll, pitch, yaw] and [vx, vy, vz, roll, pitch, yaw rate]
    z, czx, czy, czz = float(-altitude_m), 0.0, 0.0, ne
    if estimate.altitude is not None:  # NED: z = -height, so its covariances change sign
        height = estimate.altitude
        z, czx, czy, czz = -height.height_m, -height.cov_xy[0], -height.cov_xy[1], height.var
    pose_upper = (c00, c01, czx, 0.0, 0.0, c02) + (c11, czy, 0.0, 0.0, c12) + (czz, 0.0, 0.0, 0.0)
    pose_upper += (ne, 0.0, 0.0) + (ne, 0.0) + (c22,)
    velocity_upper = (float(estimate.speed_var), 0.0, 0.0, 0.0, 0.0, 0.0) + (ne, 0.0, 0.0, 0.0, 0.0)
    velocity_upper += (ne, 0.0, 0.0, 0.0) + (ne, 0.0, 0.0) + (ne, 0.0) + (float(estimate.yaw_rate_var),)
    return (
        (estimate.stamp_us, x, y, float(z), float(np.cos(half)), 0.0, 0.0, float(np.sin(half)))
        + (float(estimate.speed_mps), 0.0, 0.0, 0.0, 0.0, float(estimate.yaw_rate_radps))
        + pose_upper
        + velocity_upper
        + (_LOCAL_NED, _BODY_FRD, reset_counter % 256, mavlink2.MAV_ESTIMATOR_TYPE_GPS_INS, 100)
    )


def _usable_covariance(C: np.ndarray) -> bool:
    """Positive definite with a sane condition (Cholesky succeeds) and no variance above MAX_VARIANCE.
    C (3, 3) is symmetric by construction (rebuilt from the upper triangle). Written out: this runs
    for every frame the ground station and the neighbours receive."""
    (a, b, c), (_, d, e), (_, _, f) = C.tolist()
    if not max(a, d, f) <= MAX_VARIANCE or not a > 0.0:
        return False
    l00 = math.sqrt(a)
    l10, l20 = b / l00, c / l00
    d1 = d - l10 * l10
    if not d1 > 0.0:
        return False
    l11 = math.sqrt(d1)
    l21 = (e - l20 * l10) / l11
    d2 = f - l20 * l20 - l21 * l21
    if not d2 > 0.0:
        return False
    diagonal = (l00, l11, math.sqrt(d2))
    return min(diagonal) > 1e-9 * max(diagonal)


def _full_covariance(upper: list[float]) -> np.ndarray:
    """21 floats (upper-right triangle, row-major) -> symmetric (6, 6)."""
    return np.asarray(upper, dtype=np.float64)[_SYMMETRIC_INDEX]
