"""The motion of a vehicle state: the unicycle of the cooperative-localization paper on [x, y, theta,
gyro_bias] (vehicle.models.unicycle), the GNSS error states' decay (vehicle.models.gnss_error), and the
states added after them (vehicle.models.added_states): odometry scale states that scale the inputs
and random-walk, the camera's range scale (a random walk the motion does not depend on), and
Gauss-Markov error states that decay. States after ``moving_dim`` (a SLAM map) do not move.

``step`` is the linearized step: the new moving part of the state (q,) and F, Q (q, q). With
first-estimates Jacobians (Huang et al. 2008, used by ``ekf-slam``) the heading's effect on the
position is the displacement between propagated estimates, not the current estimate's. Pure.
"""

from __future__ import annotations

import numpy as np

from vehicle.models import added_states, unicycle
from vehicle.models.gnss_error import GnssErrorModel, augment_motion
from vehicle.models.input_noise import InputNoise

POSE_DIM = 4  # [x, y, theta, gyro_bias]


class UnicycleMotion:
    """See the module docstring. ``wheel_scales``: two odometry scale states right after the base
    states (pose, GNSS error states); ``range_scale``: one camera range-scale state after them;
    ``first_estimates``: first-estimates Jacobians."""

    def __init__(
        self,
        *,
        gnss_error: GnssErrorModel | None = None,
        wheel_scales: bool = False,
        range_scale: bool = False,
        first_estimates: bool = False,
    ) -> None:
        self.gnss_error, self.wheel_scales, self.range_scale = gnss_error, wheel_scales, range_scale
        self.first_estimates = first_estimates
        self.base_dim = POSE_DIM + (0 if gnss_error is None else 2)

    def pose_only(self, x: np.ndarray) -> bool:
        """True when the state is the bare [x, y, theta, b] and its step has the closed form
        (unicycle.predict_fast)."""
        return len(x) == POSE_DIM and self.gnss_error is None and not self.first_estimates

    def base(
        self, x: np.ndarray, speed: float, rate: float, dt: float, noise: InputNoise
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The new base state (base_dim,) and F, Q (base_dim, base_dim): the unicycle's step and the
        GNSS error states' decay."""
        head, F, Q = unicycle.motion_model(x[:POSE_DIM], speed, rate, dt, **noise.kwargs())
        if self.gnss_error is None:
            return head, F, Q
        F, Q = augment_motion(F, Q, self.gnss_error, dt)
        return np.concatenate([head, F[4, 4] * x[4:6]]), F, Q

    def step(
        self,
        x: np.ndarray,
        speed: float,
        rate: float,
        dt: float,
        noise: InputNoise,
        *,
        decaying: tuple[int, np.ndarray, np.ndarray, int] | None = None,
        prior_xy: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The linearized step of the moving part of x: (x_next (q,), F (q, q), Q (q, q)).
        ``decaying`` = (first index, correlation times (k,) s, stationary variances (k,), q): the
        Gauss-Markov states from the first index to q; None: nothing moves after the base states but
        the scale states. ``prior_xy``: the position as last propagated (first estimates)."""
        b, coupling = self.base_dim, None
        if self.wheel_scales:  # a fresh gyro's rate is not the wheels'
            speed, rate, noise, coupling = added_states.scaled_inputs(
                x, b, speed, rate, dt, noise, wheel_rate=not noise.use_bias
            )
        if self.range_scale:  # a random walk like the wheels' scales; the motion does not depend on it
            coupling = added_states.with_unused_scale(coupling, b)
        head, F, Q = unicycle.motion_model(x[:POSE_DIM], speed, rate, dt, **noise.kwargs())
        if self.first_estimates and prior_xy is not None:
            F[0, 2], F[1, 2] = -(head[1] - prior_xy[1]), head[0] - prior_xy[0]
        if self.gnss_error is not None:
            F, Q = augment_motion(F, Q, self.gnss_error, dt)
            head = np.concatenate([head, F[4, 4] * x[4:6]])
        if decaying is None:
            return head, F, Q
        first, taus, variances, moving = decaying
        if moving <= b:
            return head, F, Q
        decay, decay_var = added_states.decays(dt, taus, variances)
        walk_var = added_states.SCALE_WALK_PER_RTSEC**2 * dt
        F, Q = added_states.transition(moving, F, Q, coupling, walk_var, decay, decay_var, first)
        tail = x[b:moving].copy()
        tail[first - b :] *= decay
        return np.concatenate([head, tail]), F, Q
