"""``ukf``: the default vehicle filter with the unscented transform where the models are nonlinear
(cooperative-localization paper: UKF, sigma points with lambda scaling). Same state [x, y, theta,
gyro_bias], inputs, GNSS health, divergence guard and fusion-horizon behaviour as ``ekf``:

- prediction: every sigma point follows the exact arc of the inputs' hold pieces with its own gyro
  bias, the heading mean is circular; the inputs' noise enters as additive Q (held-input model);
- cooperative fixes: range and bearing to the neighbour through sigma points (bearing residuals
  wrapped), fused by Covariance Intersection with the neighbour's broadcast covariance added to the
  measurement noise, as in ``ekf``;
- GNSS is linear in the state: the unscented update equals the Kalman update, so it is one.

Pure: no bus, no clock.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bus.angles import wrap_angle
from vehicle import unicycle_ekf as ekf
from vehicle import unscented as ut
from vehicle.cooperative import CooperativeFix, ci_weight_from, inverse2, neighbour_measurement, relative_model
from vehicle.ekf import UpdateResult
from vehicle.estimators.ekf import UnicycleEkf


class UnicycleUkf(UnicycleEkf):
    """UKF over [x, y, theta, gyro_bias] (4,): see the module docstring."""

    name = "ukf"

    def _predict(self, speed: float, rate: float, dt: float, **noise: Any) -> None:
        use_bias, steps = noise["use_bias"], noise["steps"]
        _, Q = ekf.linearized_motion(self.x, speed, rate, dt, **noise)

        def move(point: np.ndarray) -> np.ndarray:
            bias = point[3] if use_bias else 0.0
            if steps:
                return ekf.propagate_pieces(point, steps, bias)
            return ekf.propagate_mean(point, speed, rate - bias, dt)

        self.x, self.P = ut.propagate(self.x, self.P, move, Q)

    def _cooperative_update(self, fix: CooperativeFix) -> UpdateResult:
        """CI with the unscented range-bearing prediction: P_w = P / w, R_w = R_eff / (1 - w)."""
        def h(point: np.ndarray) -> np.ndarray:
            return relative_model(point[:3], fix.neighbour_xy_m)[0]

        z_hat, M, P_xz = ut.measure(self.x, self.P, h, angle_rows=(1,))
        _, _, R = neighbour_measurement(self.x[:3], fix)  # the neighbour's covariance as noise, as in ekf
        y = np.array([fix.range_m - z_hat[0], wrap_angle(fix.bearing_rad - z_hat[1])])
        nis = float(y @ inverse2(M + R) @ y)
        if not nis / self._gate <= 1.0:
            return UpdateResult(False, nis, nis / self._gate)
        w = ci_weight_from(M, R, len(self.x))
        S = M / w + R / (1.0 - w)
        K = (P_xz / w) @ inverse2(S)
        self.x = self.x + K @ y
        self.x[2] = wrap_angle(float(self.x[2]))
        P_new = self.P / w - K @ S @ K.T
        self.P = 0.5 * (P_new + P_new.T)
        return UpdateResult(True, nis, nis / self._gate)
