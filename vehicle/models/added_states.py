"""States a filter adds after its pose for errors of its sensors that persist in time: the wheel
odometry's scale errors and the camera's time-correlated range errors (``known-map``), and the
state surgery the vehicle filters and the centralized reference share: inserting uncorrelated
states, marginalizing states out, resetting a state's spread. Functions on (x (n,), P (n, n)).

Odometry scale: the robot moves at (1 + k_v) times the speed and (1 + k_w) times the yaw rate its
odometry reports (Thrun et al., Probabilistic Robotics, 5.4: systematic odometry error; estimated
as states, as in odometry self-calibration). Range error: a sighting reads range r (1 + s_l) + white
noise, s_l a first-order Gauss-Markov process per landmark (stationary sigma sigma_s, correlation
time tau): x_{k+1} = phi x_k + w, phi = exp(-dt / tau), var(w) = sigma_s^2 (1 - phi^2).
"""

from __future__ import annotations

import math

import numpy as np

from vehicle.models.input_noise import InputNoise

SCALE_WALK_PER_RTSEC = 1e-3  # the odometry scale states' random walk (1/sqrt(s)): wheels wear, loads change
WHITE_FLOOR = 0.1  # of a sighting's range variance, at least this much is taken as white


def insert_states(
    x: np.ndarray, P: np.ndarray, at: int, x_new: np.ndarray, P_new: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """x (n,), P (n, n) with states x_new (k,), covariance P_new (k, k), inserted before index ``at``,
    uncorrelated with the others."""
    n, k = len(x), len(x_new)
    others = np.r_[0:at, at + k : n + k]
    grown = np.zeros((n + k, n + k))
    grown[np.ix_(others, others)] = P
    grown[at : at + k, at : at + k] = P_new
    return np.concatenate([x[:at], x_new, x[at:]]), grown


def append_states(x: np.ndarray, P: np.ndarray, variances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """x (n,), P (n, n) grown by len(variances) states at 0, uncorrelated, with those variances."""
    return insert_states(x, P, len(x), np.zeros(len(variances)), np.diag(variances))


def set_spread(P: np.ndarray, indices: list[int], variances: np.ndarray) -> None:
    """In place: the states at ``indices`` get these variances, uncorrelated with every other state."""
    P[indices, :] = 0.0
    P[:, indices] = 0.0
    P[indices, indices] = variances


def drop_states(x: np.ndarray, P: np.ndarray, indices: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """x, P with the states at ``indices`` marginalized out (a Gaussian's marginal: rows and
    columns deleted)."""
    mask = np.ones(len(x), dtype=bool)
    mask[indices] = False  # the same sorted indices as np.setdiff1d, without its sorting
    keep = np.flatnonzero(mask)
    return x[keep], P[np.ix_(keep, keep)]


def scaled_steps(
    steps: list[tuple[float, float, float]] | None, k_speed: float, k_rate: float
) -> list[tuple[float, float, float]] | None:
    """Input pieces [(dt s, speed m/s, yaw rate rad/s)] as the robot really moved them."""
    if not steps:
        return steps
    return [(dt, v * (1.0 + k_speed), w * (1.0 + k_rate)) for dt, v, w in steps]


def scale_jacobian(theta: float, speed: float, rate: float, dt: float, k_speed: float, k_rate: float) -> np.ndarray:
    """d [x, y, theta] / d [k_v, k_w] (3, 2) of one midpoint motion step with the reported
    ``speed`` (m/s) and ``rate`` (rad/s) over ``dt`` (s)."""
    true_speed, true_rate = speed * (1.0 + k_speed), rate * (1.0 + k_rate)
    mid = theta + 0.5 * true_rate * dt
    c, s = math.cos(mid), math.sin(mid)
    half_turn = 0.5 * rate * dt * true_speed * dt  # d mid / d k_w times the chord
    return np.array([[speed * dt * c, -half_turn * s], [speed * dt * s, half_turn * c], [0.0, rate * dt]])


def with_unused_scale(coupling: np.ndarray | None, head: int) -> np.ndarray:
    """The coupling (head, c) of a motion step to its scale states, grown by a column of zeros for one
    more scale state the motion does not depend on (the camera's range scale; None: no other scale
    states, a (head, 1) column)."""
    column = np.zeros((head, 1))
    return column if coupling is None else np.hstack([coupling, column])


def scaled_inputs(
    x: np.ndarray, scales_at: int, speed: float, rate: float, dt: float, noise: InputNoise, wheel_rate: bool
) -> tuple[float, float, InputNoise, np.ndarray]:
    """The inputs as the robot really moved them, given the scale states [k_v, k_w] at x[scales_at:]:
    speed (m/s), yaw rate (rad/s), the noise arguments with their hold pieces scaled too, and the
    coupling d [x, y, theta, ...] / d [k_v, k_w] (scales_at, 2) of the motion step. ``wheel_rate``:
    the yaw rate is the wheels' (a gyro's is not scaled; column k_w is then zero)."""
    k_speed, k_rate = float(x[scales_at]), float(x[scales_at + 1]) if wheel_rate else 0.0
    noise = noise.with_steps(scaled_steps(noise.steps, k_speed, k_rate))
    coupling = np.zeros((scales_at, 2))
    coupling[:3] = scale_jacobian(float(x[2]), speed, rate, dt, k_speed, k_rate)
    coupling[:, 1] *= wheel_rate
    return speed * (1.0 + k_speed), rate * (1.0 + k_rate), noise, coupling


def persisting_sighting(
    H: np.ndarray,
    R: np.ndarray,
    predicted: np.ndarray,
    x: np.ndarray,
    *,
    range_state: int | None = None,
    range_column: int | None = None,
    range_sigma_per_m: float = 0.0,
    bearing_state: int | None = None,
    bearing_column: int | None = None,
    bearing_var: float = 0.0,
    scale_state: int | None = None,
    scale_column: int | None = None,
    white_floor: float = WHITE_FLOOR,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A range-bearing sighting's model when its errors that persist are states of x: range read =
    r (1 + k + s) + white, bearing read = beta + b + white, k = x[scale_state] (the camera's range
    scale, every subject's), s = x[range_state], b = x[bearing_state] (the subject's own; any may be
    None). H (2, q) and predicted [range m, bearing rad] (2,) of the plain model become these (row 0
    times 1 + k + s, d range / d s = d range / d k = r in ``range_column`` and ``scale_column`` of H;
    d bearing / d b = 1 in ``bearing_column``; a column defaults to its state's index, for an H over
    all of x); R (2, 2), the reported noise, keeps only its white part (:func:`white_part`). Returns
    new arrays."""
    H, predicted = H.copy(), np.array(predicted, dtype=float)
    R = white_part(
        R,
        predicted[0],
        range_sigma_per_m if range_state is not None else 0.0,
        bearing_var if bearing_state is not None else 0.0,
        white_floor,
    )
    stretching = [
        (state, column)
        for state, column in ((range_state, range_column), (scale_state, scale_column))
        if state is not None
    ]
    if stretching:
        stretch = 1.0 + sum(float(x[state]) for state, _ in stretching)
        H[0] *= stretch
        for state, column in stretching:
            H[0, state if column is None else column] = predicted[0]
        predicted[0] *= stretch
    if bearing_state is not None:
        H[1, bearing_state if bearing_column is None else bearing_column] = 1.0
        predicted[1] += float(x[bearing_state])
    return H, R, predicted


def in_columns(model: dict, idx: list[int]) -> dict:
    """:func:`persisting_sighting`'s state arguments ``model`` for an H over the states ``idx`` only:
    each error state's column is its place in ``idx``."""
    out = dict(model)
    for state, column in (
        ("range_state", "range_column"),
        ("bearing_state", "bearing_column"),
        ("scale_state", "scale_column"),
    ):
        if model.get(state) is not None:
            out[column] = idx.index(model[state])
    return out


def white_part(
    R: np.ndarray, range_m: float, range_sigma_per_m: float, bearing_var: float, white_floor: float = WHITE_FLOOR
) -> np.ndarray:
    """The white part (2, 2) of a sighting's reported noise R at range ``range_m``: less the persisting
    (range_sigma_per_m range_m)^2 and ``bearing_var``, at least ``white_floor`` of each reported variance."""
    white = np.array(R, dtype=float)
    white[0, 0] = max(R[0, 0] - (range_sigma_per_m * range_m) ** 2, white_floor * R[0, 0])
    white[1, 1] = max(R[1, 1] - bearing_var, white_floor * R[1, 1])
    return white


def decays(dt: float, taus: np.ndarray, variances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """phi and the process noise variance (k,) of one step of k Gauss-Markov states with correlation
    times ``taus`` (k,) s and stationary ``variances`` (k,)."""
    phi = np.exp(-dt / np.asarray(taus, dtype=float))
    return phi, np.asarray(variances, dtype=float) * (1.0 - phi * phi)


def transition(
    n: int,
    F_head: np.ndarray,
    Q_head: np.ndarray,
    coupling: np.ndarray | None,
    scale_walk_var: float,
    decay: float | np.ndarray,
    decay_var: float | np.ndarray,
    first_decaying: int,
) -> tuple[np.ndarray, np.ndarray]:
    """F and Q (n, n) of one motion step of a state laid out [head (h), scale states (c), decaying
    states (from ``first_decaying`` on)]: the head moves by F_head (h, h) with noise Q_head and
    depends on the scale states through ``coupling`` (h, c) (None: no scale states); the scale
    states random-walk with ``scale_walk_var`` each; the decaying states decay by ``decay`` with
    ``decay_var`` noise (each, or one per decaying state). Written as full matrices (n stays below ~40)."""
    h = len(F_head)
    F, Q = np.eye(n), np.zeros((n, n))
    F[:h, :h] = F_head
    Q[:h, :h] = Q_head
    scales = np.arange(h, h + (0 if coupling is None else coupling.shape[1]))
    if coupling is not None:
        F[:h, scales] = coupling
    decaying = np.arange(first_decaying, n)
    F[decaying, decaying] = decay
    Q[scales, scales] = scale_walk_var
    Q[decaying, decaying] = decay_var
    return F, Q
