"""The update strategies a vehicle filter is built with: ``Linearized`` (the EKF: the motion through
its Jacobians F and Q, neighbours' fixes linearized) and ``Unscented`` (the cooperative-localization
paper's UKF: sigma points through the exact arcs of the inputs, the heading's mean circular, and the
fixes' range and bearing through sigma points of the pose). GNSS is linear in the state: its
unscented update equals the Kalman update, so both strategies make that one. Pure."""

from __future__ import annotations

import numpy as np

from vehicle.estimators.parts import ErrorStates, MotionModel, Store
from vehicle.estimators.state import FilterState, frozen
from vehicle.models import unicycle
from vehicle.models import unscented as ut
from vehicle.models.input_noise import InputNoise


class Linearized:
    """EKF prediction: the closed form for a bare 4-state filter held in plain arrays
    (unicycle.predict_fast), else the motion model's F and Q applied by the filter's store."""

    unscented_fixes = False

    def predict(
        self,
        s: FilterState,
        store: Store,
        motion: MotionModel,
        errors: ErrorStates | None,
        speed: float,
        rate: float,
        dt: float,
        noise: InputNoise,
    ) -> None:
        if store.dense and motion.pose_only(s.x):
            s.x, s.P = unicycle.predict_fast(s.x, s.P, speed, rate, dt, **noise.kwargs())
            return
        decaying = None if errors is None else errors.decaying(s)
        x_next, F, Q = motion.step(s.x, speed, rate, dt, noise, decaying=decaying, prior_xy=s.prior_xy)
        store.move(s, F, Q, x_next)
        if motion.first_estimates:
            s.prior_xy = frozen(x_next[:2].copy())


class Unscented:
    """UKF prediction: every sigma point follows the exact arc of the inputs' hold pieces with its own
    gyro bias; the inputs' noise enters as additive Q (held-input model); the GNSS error states decay
    linearly. Needs a dense store (the state is replaced)."""

    unscented_fixes = True

    def predict(
        self,
        s: FilterState,
        store: Store,
        motion: MotionModel,
        errors: ErrorStates | None,
        speed: float,
        rate: float,
        dt: float,
        noise: InputNoise,
    ) -> None:
        use_bias, steps = noise.use_bias, noise.steps
        _, F, Q = motion.base(s.x, speed, rate, dt, noise)  # Q; F only for the GNSS error states' decay
        decay = F[4, 4] if len(s.x) > 4 else 1.0

        def move(point: np.ndarray) -> np.ndarray:
            bias = point[3] if use_bias else 0.0
            if steps:
                head = unicycle.propagate_pieces(point[:4], steps, bias)
            else:
                head = unicycle.propagate_mean(point[:4], speed, rate - bias, dt)
            return head if len(point) == 4 else np.concatenate([head, decay * point[4:]])

        s.x, s.P = ut.propagate(s.x, s.P, move, Q)
