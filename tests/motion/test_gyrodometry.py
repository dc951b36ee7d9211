"""Gyro-aided wheel odometry: the gyro's turn replaces the wheels' heading; the bias is learnt at standstill."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.geometry import Pose2D
from mjnav.motion.gyrodometry import GyroOdometry


def _drive(
    fused: GyroOdometry, *, turn_scale: float, gyro_bias: float, still_s: float, rng: np.random.Generator
) -> tuple[Pose2D, Pose2D, Pose2D]:
    """Stand still ``still_s``, then drive a 90° arc and 3 m straight (0.5 m/s). The wheels see every turn
    ``turn_scale`` times too large (a wrong wheel separation); the gyro (100 Hz) has ``gyro_bias`` and 0.005 rad/s
    noise. Returns (true, wheel, fused) final poses."""
    dt = 0.01
    true = wheel = Pose2D(0.0, 0.0, 0.0)
    t = 0.0
    phases = [(still_s, 0.0, 0.0), (math.pi / 2 / 0.5, 0.5, 0.5), (6.0, 0.5, 0.0)]  # (duration, v, ω)
    fused.add_odom(t, wheel)
    for duration, v, w in phases:
        for _ in range(round(duration / dt)):
            t += dt
            true = true * Pose2D(v * dt, 0.0, w * dt)
            wheel = wheel * Pose2D(v * dt, 0.0, turn_scale * w * dt)
            fused.add_gyro(t, w + gyro_bias + rng.normal(0.0, 0.005))
            if round(t / dt) % 2 == 0:  # odometry at 50 Hz
                out = fused.add_odom(t, wheel)
    return true, wheel, out


def test_the_gyro_fixes_the_heading_of_a_wrong_wheel_separation() -> None:
    true, wheel, fused = _drive(
        GyroOdometry(), turn_scale=1.03, gyro_bias=0.0, still_s=0.0, rng=np.random.default_rng(3)
    )
    wheel_error = math.hypot(wheel.x - true.x, wheel.y - true.y)
    fused_error = math.hypot(fused.x - true.x, fused.y - true.y)
    assert wheel_error > 0.1  # 3 % of a quarter turn: 2.7°, 0.14 m off after 3 m
    assert fused_error < 0.02 and abs(fused.theta - true.theta) < 0.005


def test_the_bias_is_learnt_while_standing_still() -> None:
    learnt = GyroOdometry(bias_gain=0.05)
    true, _, fused = _drive(learnt, turn_scale=1.0, gyro_bias=0.02, still_s=5.0, rng=np.random.default_rng(4))
    assert learnt.bias_radps == pytest.approx(0.02, abs=0.002)
    assert abs(fused.theta - true.theta) < 0.01
    # Without bias estimation the 0.02 rad/s bias turns the 9 s drive 0.18 rad off.
    _, _, blind = _drive(GyroOdometry(bias_gain=0.0), turn_scale=1.0, gyro_bias=0.02, still_s=5.0,
                         rng=np.random.default_rng(4))  # fmt: skip
    assert abs(blind.theta - true.theta) > 0.15


def test_without_gyro_samples_the_wheels_heading_is_kept() -> None:
    odo = GyroOdometry()
    odo.add_odom(0.0, Pose2D(0.0, 0.0, 0.0))
    first = odo.add_odom(0.02, Pose2D(0.01, 0.0, 0.02))
    assert (first.x, first.y, first.theta) == pytest.approx((0.01, 0.0, 0.02), abs=1e-4)
    odo.add_gyro(0.03, 0.0)
    odo.add_gyro(0.04, 0.0)
    assert odo.add_odom(0.04, Pose2D(0.02, 0.0, 0.04)).theta == pytest.approx(0.02)  # the gyro says: no turn
    odo.add_gyro(0.05, 1.0)  # the sample of 0.06 has not come: the one there is stands for the whole interval
    assert odo.add_odom(0.06, Pose2D(0.03, 0.0, 0.05)).theta == pytest.approx(0.02 + 1.0 * 0.02)
    odo.reset()
    assert odo.pose is None and odo.add_odom(1.0, Pose2D(5.0, 5.0, 1.0)) == Pose2D(5.0, 5.0, 1.0)
