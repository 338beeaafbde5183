"""EKF for a unicycle at constant altitude with gyro-bias estimation (pure maths).

State x = [x_m, y_m, theta_rad, gyro_bias_radps] (4,). Inputs: forward speed from wheel odometry and
yaw rate from the gyro minus the estimated bias (or odometry yaw rate when the gyro is silent), as
their means over the propagation interval. Motion model (cooperative-localization paper):
x + v dt cos(theta), y + v dt sin(theta), theta + w dt, integrated here along the exact arc.
GNSS observes [x, y].
"""

from __future__ import annotations

import math

import numpy as np

from bus.angles import wrap_angle as wrap
from vehicle.models.kalman import UpdateResult, gated_update

STATE_DIM = 4
H_GNSS = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


def propagate_mean(x: np.ndarray, speed_mps: float, yaw_rate_radps: float, dt_s: float) -> np.ndarray:
    """Exact arc propagation of the state (4,); the bias is already removed from yaw_rate_radps."""
    dtheta = yaw_rate_radps * dt_s
    chord = speed_mps * dt_s * np.sinc(dtheta / (2.0 * np.pi))
    mid = x[2] + 0.5 * dtheta
    return np.array([x[0] + chord * np.cos(mid), x[1] + chord * np.sin(mid), wrap(x[2] + dtheta), x[3]])


def pieces(speed: list[tuple[int, float]], rate: list[tuple[int, float]]) -> list[tuple[float, float, float]]:
    """Merge two inputs' hold segments [(duration us, value)] over one interval into pieces
    [(dt s, speed, rate)] on which both are constant."""
    out, i, j = [], 0, 0
    left_v = speed[0][0] if speed else 0
    left_w = rate[0][0] if rate else 0
    while i < len(speed) and j < len(rate):
        step = min(left_v, left_w)
        if step > 0:
            out.append((step * 1e-6, speed[i][1], rate[j][1]))
        left_v, left_w = left_v - step, left_w - step
        if left_v == 0:
            i += 1
            left_v = speed[i][0] if i < len(speed) else 0
        if left_w == 0:
            j += 1
            left_w = rate[j][0] if j < len(rate) else 0
    return out


def propagate_pieces(x: np.ndarray, steps: list[tuple[float, float, float]], bias: float) -> np.ndarray:
    """Exact arc propagation of the state (4,) over pieces [(dt s, speed, measured rate)] with the
    rate's bias removed: exact for inputs held constant on each piece (as they are sampled)."""
    px, py, th = float(x[0]), float(x[1]), float(x[2])
    for dt, v, w in steps:
        dtheta = (w - bias) * dt
        half = 0.5 * dtheta
        chord = v * dt * (math.sin(half) / half if abs(half) > 1e-9 else 1.0 - half * half / 6.0)
        mid = th + half
        px, py, th = px + chord * math.cos(mid), py + chord * math.sin(mid), th + dtheta
    return np.array([px, py, wrap(th), x[3]])


def motion_jacobians(
    x: np.ndarray, speed_mps: float, yaw_rate_radps: float, dt_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """F = d f / d x (4, 4) and G = d f / d [v, w] (4, 2), midpoint approximation of the arc."""
    mid = x[2] + 0.5 * yaw_rate_radps * dt_s
    c, s = np.cos(mid), np.sin(mid)
    half_v_dt2 = 0.5 * speed_mps * dt_s * dt_s
    G = np.array([[dt_s * c, -half_v_dt2 * s], [dt_s * s, half_v_dt2 * c], [0.0, dt_s], [0.0, 0.0]])
    F = np.eye(STATE_DIM)
    F[0, 2], F[1, 2] = -speed_mps * dt_s * s, speed_mps * dt_s * c
    F[:3, 3] = -G[:3, 1]  # the bias enters as w_true = w_measured - bias
    return F, G


def linearized_motion(
    x: np.ndarray,
    speed_mps: float,
    yaw_rate_radps: float,
    dt_s: float,
    *,
    speed_var: float,
    yaw_rate_var: float,
    bias_walk_var: float,
    use_bias: bool = True,
    steps: list[tuple[float, float, float]] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """F (4, 4) and Q (4, 4) of the motion over dt_s with the mean inputs of the interval, so that
    P <- F P F^T + Q (``steps`` is accepted for the same call as :func:`motion_model`, unused).

    ``yaw_rate_radps`` is the measured (gyro) mean rate; the bias x[3] is removed when ``use_bias``.
    ``speed_var`` (m^2/s^2) and ``yaw_rate_var`` (rad^2/s^2) are the variances of those *means*;
    ``bias_walk_var`` (rad^2/s^3) is the bias random walk's rate. Q = G diag(var) G^T.
    """
    yaw_rate = yaw_rate_radps - (x[3] if use_bias else 0.0)
    F, G = motion_jacobians(x, speed_mps, yaw_rate, dt_s)
    if not use_bias:
        F[:, 3] = 0.0
        F[3, 3] = 1.0
    Q = np.outer(G[:, 0] * speed_var, G[:, 0]) + np.outer(G[:, 1] * yaw_rate_var, G[:, 1])
    Q[3, 3] += bias_walk_var * dt_s
    return F, Q


def motion_model(
    x: np.ndarray,
    speed_mps: float,
    yaw_rate_radps: float,
    dt_s: float,
    *,
    speed_var: float,
    yaw_rate_var: float,
    bias_walk_var: float,
    use_bias: bool = True,
    steps: list[tuple[float, float, float]] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The new state (4,) and :func:`linearized_motion`'s F and Q. With ``steps`` (the inputs' hold
    pieces) the mean follows every piece's arc exactly; the covariance is propagated once with the
    mean inputs."""
    F, Q = linearized_motion(
        x,
        speed_mps,
        yaw_rate_radps,
        dt_s,
        speed_var=speed_var,
        yaw_rate_var=yaw_rate_var,
        bias_walk_var=bias_walk_var,
        use_bias=use_bias,
    )
    bias = x[3] if use_bias else 0.0
    x_new = propagate_pieces(x, steps, bias) if steps else propagate_mean(x, speed_mps, yaw_rate_radps - bias, dt_s)
    return x_new, F, Q


def predict(
    x: np.ndarray,
    P: np.ndarray,
    speed_mps: float,
    yaw_rate_radps: float,
    dt_s: float,
    *,
    speed_var: float,
    yaw_rate_var: float,
    bias_walk_var: float,
    use_bias: bool = True,
    steps: list[tuple[float, float, float]] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Propagate x (4,) and P (4, 4) over dt_s (see :func:`motion_model`)."""
    x_new, F, Q = motion_model(
        x,
        speed_mps,
        yaw_rate_radps,
        dt_s,
        speed_var=speed_var,
        yaw_rate_var=yaw_rate_var,
        bias_walk_var=bias_walk_var,
        use_bias=use_bias,
        steps=steps,
    )
    P_new = F @ P @ F.T + Q
    return x_new, 0.5 * (P_new + P_new.T)


def predict_fast(
    x: np.ndarray,
    P: np.ndarray,
    speed_mps: float,
    yaw_rate_radps: float,
    dt_s: float,
    *,
    speed_var: float,
    yaw_rate_var: float,
    bias_walk_var: float,
    use_bias: bool = True,
    steps: list[tuple[float, float, float]] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`predict` written out on plain floats for the 4-state filter (numpy's per-call cost
    dominates 4 x 4 products): the same F P F^T + G diag(var) G^T, term by term.

    F = I + E with E nonzero only in column 2 (a, b, 0, 0) and column 3 (d0, d1, d2, 0), so
    (F P)[i] = P[i] + E[i, 2] P[2] + E[i, 3] P[3] and (F P F^T)[i, j] adds the same on the right.
    """
    bias = float(x[3]) if use_bias else 0.0
    w = yaw_rate_radps - bias
    mid = float(x[2]) + 0.5 * w * dt_s
    c, s = math.cos(mid), math.sin(mid)
    h = 0.5 * speed_mps * dt_s * dt_s
    a, b = -speed_mps * dt_s * s, speed_mps * dt_s * c
    d0, d1, d2 = (h * s, -h * c, -dt_s) if use_bias else (0.0, 0.0, 0.0)  # d f / d bias = -d f / d w
    (p00, p01, p02, p03), (_, p11, p12, p13), (_, _, p22, p23), (_, _, _, p33) = P.tolist()
    # F P, rows 0-2 (row 3 is P's): only the entries the upper triangle of F P F^T needs
    r0 = (p00 + a * p02 + d0 * p03, p01 + a * p12 + d0 * p13, p02 + a * p22 + d0 * p23, p03 + a * p23 + d0 * p33)
    r1 = (p12 + b * p22 + d1 * p23, p13 + b * p23 + d1 * p33, p11 + b * p12 + d1 * p13)  # cols 2, 3, 1
    r2 = (p22 + d2 * p23, p23 + d2 * p33)  # cols 2, 3
    g10, g11 = dt_s * c, dt_s * s  # d f / d v = (g10, g11, 0, 0)
    g20, g21 = -h * s, h * c  # d f / d w = (g20, g21, dt, 0)
    sv, sw = speed_var, yaw_rate_var
    m00 = r0[0] + a * r0[2] + d0 * r0[3] + sv * g10 * g10 + sw * g20 * g20
    m01 = r0[1] + b * r0[2] + d1 * r0[3] + sv * g10 * g11 + sw * g20 * g21
    m02 = r0[2] + d2 * r0[3] + sw * g20 * dt_s
    m03 = r0[3]
    m11 = r1[2] + b * r1[0] + d1 * r1[1] + sv * g11 * g11 + sw * g21 * g21
    m12 = r1[0] + d2 * r1[1] + sw * g21 * dt_s
    m13 = r1[1]
    m22 = r2[0] + d2 * r2[1] + sw * dt_s * dt_s
    m23 = r2[1]
    m33 = p33 + bias_walk_var * dt_s
    P_new = np.array([[m00, m01, m02, m03], [m01, m11, m12, m13], [m02, m12, m22, m23], [m03, m13, m23, m33]])
    x_new = propagate_pieces(x, steps, bias) if steps else propagate_mean(x, speed_mps, w, dt_s)
    return x_new, P_new


def gnss_update(
    x: np.ndarray, P: np.ndarray, innovation_m: np.ndarray, H: np.ndarray, cov_m2: np.ndarray, gate: float
) -> tuple[np.ndarray, np.ndarray, UpdateResult]:
    """Fuse a horizontal position fix's innovation (2,) with H (2, n) and covariance (2, 2) behind a
    chi-square gate (H = :data:`H_GNSS` on the 4-state filter)."""
    x_new, P_new, result = gated_update(x, P, innovation_m, H, cov_m2, gate)
    x_new[2] = wrap(x_new[2])
    return x_new, P_new, result
