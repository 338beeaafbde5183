"""The AR-EKF-SLAM paper's three-dimensional EKF-SLAM model: state 6 + 3n. Pure.

State X = [p (3), v (3), X_1 (3), ..., X_n (3)]: the camera's position and velocity in the fixed frame
O_B, then each landmark's position in it (m, m/s, m). The paper's state equations:

    p_{k+1} = p_k + (v_k + Omega) dt,   v_{k+1} = v_k + Omega,   X_i still,

Omega a white Gaussian velocity increment (here of covariance ``omega_var`` I per step, m^2/s^2), so
F = [[I, dt I], [0, I]] on the head and Q = omega_var [[dt^2 I, dt I], [dt I, I]].

Observation (the paper's Z_k = X_w^f): a landmark triangulated in the body frame of the frame that
saw it (vehicle.vision.triangulation), h = R^T (X_i - p), with R = R_V^B the body's rotation into the
fixed frame, from visual odometry (not a state in the paper); H = [-R^T, 0, ..., R^T at X_i, ...].

A new landmark (the paper's initialisation): X_new = g(X_V, Z) = p + R Z, with grad g_X = [I, 0] over
[p, v] and grad g_Z = R, and the covariance blocks of the paper's P_new: cov(X_new, X_V) = grad g_X
P_vv, cov(X_new, X_M) = grad g_X P_vm, cov(X_new) = grad g_X P_vv grad g_X^T + grad g_Z R_Z grad g_Z^T.
(The paper prints the map block as grad g_Z P_mm and the last term as grad g_Z P_mm grad g_Z^T, with
P_mm standing for the observation's covariance R_Z there; the cross-covariance with the map is
the vehicle's, carried by grad g_X.)
"""

from __future__ import annotations

import numpy as np

HEAD = 6  # p, v
POINT = 3


def landmark_slice(index: int) -> slice:
    """The rows of landmark ``index`` (0-based) in the state."""
    start = HEAD + POINT * index
    return slice(start, start + POINT)


def landmarks(x: np.ndarray) -> int:
    return (len(x) - HEAD) // POINT


def predict(x: np.ndarray, P: np.ndarray, dt: float, omega_var: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One constant-velocity step of ``dt`` s (module docstring): x (6 + 3n,), P (6 + 3n, 6 + 3n);
    ``omega_var`` the velocity's white increment per step, m^2/s^2: one for every axis, or (3,) per
    axis of the fixed frame."""
    eye = np.eye(POINT)
    F = np.block([[eye, dt * eye], [np.zeros((3, 3)), eye]])
    W = np.diag(np.broadcast_to(np.asarray(omega_var, float), POINT))
    Q = np.block([[dt * dt * W, dt * W], [dt * W, W]])
    x_new = x.copy()
    x_new[:HEAD] = F @ x[:HEAD]
    P_new = P.copy()
    P_new[:HEAD, :] = F @ P[:HEAD, :]
    P_new[:, :HEAD] = P_new[:, :HEAD] @ F.T
    P_new[:HEAD, :HEAD] += Q
    return x_new, 0.5 * (P_new + P_new.T)


def observe(x: np.ndarray, index: int, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Landmark ``index`` seen from the body: h = R^T (X_i - p) (3,) and H (3, 6 + 3n)."""
    at = landmark_slice(index)
    H = np.zeros((POINT, len(x)))
    H[:, :POINT] = -rotation.T
    H[:, at] = rotation.T
    return rotation.T @ (x[at] - x[:POINT]), H


def initial_point(x: np.ndarray, z: np.ndarray, rotation: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """g(X_V, Z) = p + R Z (3,), grad g_X (3, 6) and grad g_Z (3, 3)."""
    grad_x = np.hstack([np.eye(POINT), np.zeros((POINT, POINT))])
    return x[:POINT] + rotation @ z, grad_x, rotation.copy()


def add_landmark(
    x: np.ndarray, P: np.ndarray, z: np.ndarray, R_z: np.ndarray, rotation: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The state and covariance grown by a landmark first seen at z (3,) in the body, noise R_z (3, 3)
    (the paper's P_new, module docstring)."""
    point, grad_x, grad_z = initial_point(x, z, rotation)
    cross = grad_x @ P[:HEAD, :]  # cov(X_new, X): through the vehicle's rows only
    block = grad_x @ P[:HEAD, :HEAD] @ grad_x.T + grad_z @ R_z @ grad_z.T
    P_new = np.block([[P, cross.T], [cross, block]])
    return np.concatenate([x, point]), 0.5 * (P_new + P_new.T)
