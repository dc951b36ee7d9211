"""Wheel odometry: drifts like a real robot over a scripted square, but stays bounded; exact without noise."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.geometry import Pose2D, angle_diff
from mjnav.sim import OdometryConfig, Simulator
from mjnav.sim.odometry import WheelOdometry

SIDE_M = 1.5
SPEED = 0.4
TURN = 0.8


def _drive_square(sim: Simulator) -> None:
    """Open-loop square: 4 × (1.5 m straight at 0.4 m/s, stop, 90° left turn at 0.8 rad/s, stop)."""
    t = sim.time_s
    for _ in range(4):
        for v, w, dur in (
            (SPEED, 0.0, SIDE_M / SPEED),
            (0.0, 0.0, 0.5),
            (0.0, TURN, (math.pi / 2) / TURN),
            (0.0, 0.0, 0.5),
        ):
            sim.set_command(v, w)
            t += dur
            sim.step_until(t)


def _odom_in_map(sim: Simulator) -> Pose2D:
    return sim.start_pose * sim.odometry().pose


@pytest.mark.e2e
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_odometry_drifts_but_stays_bounded_over_a_square(seed: int) -> None:
    sim = Simulator("empty", seed=seed, lidar=None, start=Pose2D(1.0, 1.0, 0.3))
    _drive_square(sim)
    truth = sim.ground_truth_pose()
    odom = _odom_in_map(sim)
    pos_err = truth.distance_to(odom)
    yaw_err = abs(angle_diff(truth.theta, odom.theta))
    travelled = 4 * SIDE_M
    assert pos_err > 1e-3 or yaw_err > 1e-3, "odometry must drift"
    assert pos_err < 0.05 * travelled  # < 30 cm after 6 m
    assert yaw_err < math.radians(8.0)


def test_odometry_without_error_model_follows_the_ground_truth() -> None:
    exact = OdometryConfig(
        ticks_per_rev=0, wheel_radius_error_std=0.0, wheel_separation_error_std=0.0, slip_noise_std=0.0
    )
    sim = Simulator("empty", seed=0, lidar=None, odometry=exact)
    _drive_square(sim)
    truth = sim.ground_truth_pose()
    odom = _odom_in_map(sim)
    # only the physical effects remain (contact compression shortens the rolling radius by < 1 %)
    assert truth.distance_to(odom) < 0.01 * 4 * SIDE_M
    assert abs(angle_diff(truth.theta, odom.theta)) < math.radians(2.0)
    assert sim.odometry().stamp_s == pytest.approx(sim.time_s, abs=0.02)


def test_odometry_starts_at_the_odom_origin_and_reports_twist() -> None:
    sim = Simulator("rooms", seed=0, lidar=None, watchdog_timeout_s=None)
    assert sim.odometry().pose == Pose2D()
    sim.set_command(0.3, 0.2)
    sim.step_until(1.0)
    twists = []
    for k in range(50):  # every 50 Hz update for a second: each one is noisy (slip noise), the mean is not
        sim.step_until(1.0 + 0.02 * (k + 1))
        est = sim.odometry()
        assert est.stamp_s == pytest.approx(sim.time_s)
        twists.append((est.v_mps, est.omega_radps))
    v, w = np.mean(twists, axis=0)
    assert v == pytest.approx(0.3, rel=0.03)
    assert w == pytest.approx(0.2, rel=0.05)


def test_wheel_odometry_integrates_straight_and_turning_increments() -> None:
    rng = np.random.default_rng(0)
    odo = WheelOdometry(
        0.1,
        0.28,
        OdometryConfig(ticks_per_rev=0, wheel_radius_error_std=0, wheel_separation_error_std=0, slip_noise_std=0),
        rng,
    )
    odo.reset(0.0, 0.0, 0.0)
    est = odo.update(1.0, 10.0, 10.0)  # 10 rad on both wheels = 0.5 m
    assert (est.pose.x, est.pose.y, est.pose.theta) == pytest.approx((0.5, 0.0, 0.0))
    assert est.v_mps == pytest.approx(0.5)
    turn = 2 * 0.28 * (math.pi / 2) / 0.1  # wheel-angle difference for a 90° turn: Δθ = W/(2L)·Δ
    est = odo.update(2.0, 10.0 - turn / 2, 10.0 + turn / 2)
    assert est.pose.theta == pytest.approx(math.pi / 2)
    assert est.omega_radps == pytest.approx(math.pi / 2)
    quantised = WheelOdometry(
        0.1,
        0.28,
        OdometryConfig(ticks_per_rev=4, wheel_radius_error_std=0, wheel_separation_error_std=0, slip_noise_std=0),
        rng,
    )
    quantised.reset(0.0, 0.0, 0.0)
    assert quantised.update(0.1, 1.0, 1.0).pose.x == 0.0  # less than a quarter turn: no tick yet
    assert quantised.update(0.2, 1.6, 1.6).pose.x == pytest.approx(0.05 * math.pi / 2)
