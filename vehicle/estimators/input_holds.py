"""What a vehicle filter does with its input samples: holds them (vehicle.estimators.inputs) until the next
prediction closes them (vehicle.estimators.propagation). The gyro's rate, with the accelerometer
telling the slip guard whether the wheels spin; the wheels' speed (slip taken off) and yaw rate;
visual odometry's speed and yaw rate with the variances of their fit. Pure."""

from __future__ import annotations

import numpy as np

from bus import messages as m
from bus.config import SensorSpec
from bus.topics import Topic
from vehicle.estimators.state import FilterState
from vehicle.vision.motion import VisualMotion


def hold_imu(s: FilterState, msg: m.ImuSample) -> None:
    s.gyro.sample(msg.stamp_us, float(msg.gyro_radps[2]))
    s.slip.accelerometer(float(msg.accel_mps2[0]))


def hold_wheels(s: FilterState, msg: m.WheelOdometry) -> None:
    s.speed.sample(msg.stamp_us, s.slip.correct(msg.stamp_us, msg.speed_mps))
    s.odom_yaw.sample(msg.stamp_us, msg.yaw_rate_radps)


def hold_row(s: FilterState, topic: str, stamp_us: int, row: list[float]) -> None:
    """An IMU or wheel odometry sample as its feed row (bus.feed.LAYOUT, floats): what
    :func:`hold_imu` and :func:`hold_wheels` do with its message."""
    if topic == Topic.IMU:
        s.gyro.sample(stamp_us, row[2])
        s.slip.accelerometer(row[3])
    else:
        s.speed.sample(stamp_us, s.slip.correct(stamp_us, row[0]))
        s.odom_yaw.sample(stamp_us, row[1])


def hold_visual(s: FilterState, msg: VisualMotion, spec: SensorSpec, camera_period_us: int) -> None:
    """Visual odometry's motion (its samples a camera period apart); an infinite yaw-rate variance:
    the yaw rate stays the gyro's."""
    s.speed.period_us = s.odom_yaw.period_us = camera_period_us
    s.speed.sample(msg.stamp_us, msg.speed_mps, msg.speed_var / max(spec.odom_speed_sigma_mps**2, 1e-12))
    if np.isfinite(msg.yaw_rate_var):
        s.visual_us = msg.stamp_us
        weight = msg.yaw_rate_var / max(spec.odom_yaw_rate_sigma_radps**2, 1e-12)
        s.odom_yaw.sample(msg.stamp_us, msg.yaw_rate_radps, weight)
