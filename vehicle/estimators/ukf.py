"""``ukf``: the default vehicle filter with the unscented transform where the models are nonlinear
(cooperative-localization paper: UKF, sigma points with lambda scaling). Same state [x, y, theta,
gyro_bias], inputs, GNSS health, divergence guard and fusion-horizon behaviour as ``ekf``:

- prediction: every sigma point follows the exact arc of the inputs' hold pieces with its own gyro
  bias, the heading mean is circular; the inputs' noise enters as additive Q (held-input model);
- cooperative fixes: range and bearing to the neighbour through sigma points of the pose marginal
  (bearing residuals wrapped), fused by the vehicle's cooperative rule as in ``ekf``;
- GNSS is linear in the state: the unscented update equals the Kalman update, so it is one;
- the GNSS error states (when the datasheet has them) decay linearly, as in ``ekf``.

Pure: no bus, no clock.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vehicle import unicycle_ekf as ekf
from vehicle import unscented as ut
from vehicle.estimators.ekf import UnicycleEkf


class UnicycleUkf(UnicycleEkf):
    """UKF over [x, y, theta, gyro_bias] (4,): see the module docstring."""

    name = "ukf"
    unscented_fixes = True

    def _predict(self, speed: float, rate: float, dt: float, **noise: Any) -> None:
        use_bias, steps = noise["use_bias"], noise["steps"]
        _, F, Q = self._motion(speed, rate, dt, **noise)  # Q; F only for the GNSS error states' decay
        decay = F[4, 4] if len(self.x) > 4 else 1.0

        def move(point: np.ndarray) -> np.ndarray:
            bias = point[3] if use_bias else 0.0
            if steps:
                head = ekf.propagate_pieces(point[:4], steps, bias)
            else:
                head = ekf.propagate_mean(point[:4], speed, rate - bias, dt)
            return head if len(point) == 4 else np.concatenate([head, decay * point[4:]])

        self.x, self.P = ut.propagate(self.x, self.P, move, Q)
