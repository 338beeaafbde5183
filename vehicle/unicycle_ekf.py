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
from vehicle.ekf import UpdateResult, gated_update

STATE_DIM = 4
_H_GNSS = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]])


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


def motion_jacobians(x: np.ndarray, speed_mps: float, yaw_rate_radps: float, dt_s: float) -> tuple[np.ndarray, np.ndarray]:
    """F = d f / d x (4, 4) and G = d f / d [v, w] (4, 2), midpoint approximation of the arc."""
    mid = x[2] + 0.5 * yaw_rate_radps * dt_s
    c, s = np.cos(mid), np.sin(mid)
    half_v_dt2 = 0.5 * speed_mps * dt_s * dt_s
    G = np.array([[dt_s * c, -half_v_dt2 * s], [dt_s * s, half_v_dt2 * c], [0.0, dt_s], [0.0, 0.0]])
    F = np.eye(STATE_DIM)
    F[0, 2], F[1, 2] = -speed_mps * dt_s * s, speed_mps * dt_s * c
    F[:3, 3] = -G[:3, 1]  # the bias enters as w_true = w_measured - bias
    return F, G


def predict(x: np.ndarray, P: np.ndarray, speed_mps: float, yaw_rate_radps: float, dt_s: float, *,
            speed_var: float, yaw_rate_var: float, bias_walk_var: float, use_bias: bool = True,
            steps: list[tuple[float, float, float]] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Propagate x (4,) and P (4, 4) over dt_s with the mean inputs of the interval.

    ``yaw_rate_radps`` is the measured (gyro) mean rate; the bias x[3] is removed when ``use_bias``.
    ``speed_var`` (m^2/s^2) and ``yaw_rate_var`` (rad^2/s^2) are the variances of those *means*;
    ``bias_walk_var`` (rad^2/s^3) is the bias random walk's rate. Q = G diag(var) G^T. With
    ``steps`` (the inputs' hold pieces) the mean follows every piece's arc exactly; the covariance
    is propagated once with the mean inputs.
    """
    yaw_rate = yaw_rate_radps - (x[3] if use_bias else 0.0)
    F, G = motion_jacobians(x, speed_mps, yaw_rate, dt_s)
    if not use_bias:
        F[:, 3] = 0.0
        F[3, 3] = 1.0
    P_new = F @ P @ F.T
    P_new += np.outer(G[:, 0] * speed_var, G[:, 0]) + np.outer(G[:, 1] * yaw_rate_var, G[:, 1])
    P_new[3, 3] += bias_walk_var * dt_s
    x_new = propagate_pieces(x, steps, x[3] if use_bias else 0.0) if steps else propagate_mean(x, speed_mps, yaw_rate, dt_s)
    return x_new, 0.5 * (P_new + P_new.T)


def gnss_update(x: np.ndarray, P: np.ndarray, fix_m: np.ndarray, cov_m2: np.ndarray,
                gate: float) -> tuple[np.ndarray, np.ndarray, UpdateResult]:
    """Fuse a horizontal position fix (2,) with covariance (2, 2) behind a chi-square gate."""
    x_new, P_new, result = gated_update(x, P, fix_m - x[:2], _H_GNSS, cov_m2, gate)
    x_new[2] = wrap(x_new[2])
    return x_new, P_new, result
