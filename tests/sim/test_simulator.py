"""Simulator behaviour: velocity tracking, saturation, watchdog, determinism, collisions, IMU, encoders."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mjnav.geometry import Pose2D
from mjnav.sim import InvalidCommandError, Simulator


def _mean_twist(sim: Simulator, t_from: float, t_to: float) -> tuple[float, float]:
    vs, ws = [], []
    sim.step_until(t_from)
    while sim.time_s < t_to - 1e-9:
        sim.step(5)
        v, w = sim.body_velocity()
        vs.append(v)
        ws.append(w)
    return float(np.mean(vs)), float(np.mean(ws))


@pytest.mark.parametrize(("v", "w"), [(0.5, 0.0), (0.3, 0.6), (0.0, 1.0), (-0.4, -0.3), (0.8, 0.2)])
def test_commanded_twist_is_tracked_within_5_percent(v: float, w: float) -> None:
    sim = Simulator("empty", seed=0, lidar=None, watchdog_timeout_s=None)
    sim.set_command(v, w)
    mv, mw = _mean_twist(sim, 1.0, 2.0)
    if v:
        assert mv == pytest.approx(v, rel=0.05)
    else:
        assert abs(mv) < 0.01
    if w:
        assert mw == pytest.approx(w, rel=0.05)
    else:
        assert abs(mw) < 0.01


def test_saturation_scales_both_wheels_and_keeps_the_curvature() -> None:
    sim = Simulator("empty", seed=0, lidar=None, watchdog_timeout_s=None)
    v, w = sim.set_command(3.0, 3.0)  # 3 m/s is beyond the 20 rad/s wheels
    assert v == pytest.approx(w) and v < 1.0
    right = (2 * v + sim.wheel_separation_m * w) / sim.wheel_diameter_m
    assert right == pytest.approx(20.0)
    mv, mw = _mean_twist(sim, 1.0, 1.5)
    assert mw / mv == pytest.approx(1.0, rel=0.05)


def test_watchdog_zeroes_the_wheels_when_the_command_is_stale() -> None:
    sim = Simulator("empty", seed=0, lidar=None)  # default timeout 0.5 s
    sim.set_command(0.5, 0.0)
    sim.step_until(0.49)
    assert not sim.watchdog_tripped
    assert sim.body_velocity()[0] > 0.3
    sim.step_until(0.5)
    assert sim.watchdog_tripped
    sim.step_until(2.0)
    assert abs(sim.body_velocity()[0]) < 0.01
    stopped_at = sim.ground_truth_pose().x
    assert 0.1 < stopped_at < 0.3  # ≈ 0.5 s of driving, then braking
    # a fresh command re-arms it; re-sending every 0.25 s keeps it alive
    for k in range(8):
        sim.set_command(0.5, 0.0)
        sim.step_until(2.0 + 0.25 * (k + 1))
    assert not sim.watchdog_tripped
    assert sim.body_velocity()[0] > 0.45


def test_without_watchdog_the_command_is_held() -> None:
    sim = Simulator("empty", seed=0, lidar=None, watchdog_timeout_s=None)
    sim.set_command(0.5, 0.0)
    sim.step_until(3.0)
    assert not sim.watchdog_tripped
    assert sim.body_velocity()[0] > 0.45


def test_invalid_command_is_rejected() -> None:
    sim = Simulator("empty", seed=0, lidar=None)
    with pytest.raises(InvalidCommandError):
        sim.set_command(math.nan, 0.0)
    with pytest.raises(InvalidCommandError):
        sim.step_until(math.inf)


def _script(sim: Simulator) -> list[object]:
    out: list[object] = []
    for k, (v, w) in enumerate([(0.4, 0.0), (0.3, 0.8), (0.5, -0.4)]):
        sim.set_command(v, w)
        sim.step_until(0.5 * (k + 1))
        scan = sim.latest_scan
        assert scan is not None
        out += [
            sim.ground_truth_pose(),
            sim.odometry().pose,
            scan.ranges_m.copy(),
            sim.imu().angular_velocity_radps,
        ]
    return out


def test_same_seed_is_bit_identical_and_seed_only_changes_the_noise() -> None:
    a = _script(Simulator("rooms", seed=3))
    b = _script(Simulator("rooms", seed=3))
    c = _script(Simulator("rooms", seed=4))
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(
            np.asarray(x if not isinstance(x, Pose2D) else x.as_array()),
            np.asarray(y if not isinstance(y, Pose2D) else y.as_array()),
        )
    # ground truth does not depend on the noise seed; sensors do
    assert a[-4] == c[-4]
    assert not np.array_equal(a[-2], c[-2])
    assert a[-3] != c[-3]


def test_driving_into_a_wall_counts_one_collision_per_event() -> None:
    # rooms: start (-3.5, -3.5) facing +x; the x = 0 partition's inner face is at x = -0.05
    sim = Simulator("rooms", seed=0, lidar=None, watchdog_timeout_s=None, start=Pose2D(-1.0, -3.5, 0.0))
    sim.set_command(0.4, 0.0)
    sim.step_until(1.5)
    assert sim.collisions == 0
    sim.step_until(6.0)  # hits at ≈ 2 s, then keeps pushing for 4 s
    assert sim.collisions == 1
    assert sim.in_collision
    assert -0.05 - 0.18 - 0.01 < sim.ground_truth_pose().x < -0.05 - 0.18 + 0.01  # chassis (r = 0.18) at the wall
    sim.set_command(-0.4, 0.0)  # back off ...
    sim.step_until(8.0)
    assert not sim.in_collision
    sim.set_command(0.4, 0.0)  # ... and hit it again
    sim.step_until(12.0)
    assert sim.collisions == 2


def test_the_moving_cart_crosses_the_route_and_hits_a_robot_standing_in_it() -> None:
    # warehouse cart: x = 0, y(t) = -3 cos(2πt/24): it reaches y = 0 at t = 6 s
    sim = Simulator("warehouse", seed=0, lidar=None, start=Pose2D(0.0, 0.0, 0.0))
    sim.step_until(3.0)
    assert sim.collisions == 0
    sim.step_until(8.0)
    assert sim.collisions >= 1
    cart = sim.model.body("cart").id
    assert sim.data.xpos[cart][1] > 0.0


def test_imu_at_rest_reads_gravity_and_no_rotation() -> None:
    sim = Simulator("empty", seed=0, lidar=None)
    sim.step_until(1.0)
    acc = np.mean([sim.imu().linear_acceleration_mps2 for _ in range(200)], axis=0)
    gyro = np.mean([sim.imu().angular_velocity_radps for _ in range(200)], axis=0)
    assert acc[2] == pytest.approx(9.81, abs=0.02)
    assert np.all(np.abs(acc[:2]) < 0.2)  # the robot rests tilted by < 1° on its rear caster
    assert np.all(np.abs(gyro) < 0.002)
    q = sim.imu().orientation_xyzw
    assert np.linalg.norm(q) == pytest.approx(1.0)


def test_imu_gyro_measures_the_turn_rate() -> None:
    sim = Simulator("empty", seed=0, lidar=None, watchdog_timeout_s=None)
    sim.set_command(0.0, 0.8)
    sim.step_until(1.5)
    gz = np.mean([sim.imu().angular_velocity_radps[2] for _ in range(100)])
    assert gz == pytest.approx(sim.body_velocity()[1], abs=0.005)


def test_wheel_states_follow_the_wheels() -> None:
    sim = Simulator("empty", seed=0, lidar=None, watchdog_timeout_s=None)
    sim.set_command(0.5, 0.0)
    sim.step_until(2.0)
    ws = sim.wheel_states()
    assert ws.names == ("left_wheel_joint", "right_wheel_joint")
    assert ws.stamp_s == pytest.approx(2.0)
    assert np.allclose(ws.velocity_radps, 10.0, atol=0.1)  # 0.5 m/s / 0.05 m
    assert np.all(ws.position_rad > 10.0)
