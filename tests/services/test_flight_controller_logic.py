"""Flight-controller logic on a real in-process bus, stepped by the test at chosen sim times: arming, offboard from a
PoseStamped setpoint, the 0.5 s failsafe, a commanded landing, the position-lost failsafe (hold, descend, land), the
geofence (return or land) and the IMU samples it takes its attitude from."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from mjnav.aerial.rep103 import quat_enu_flu_to_ned_frd
from mjnav.bus import Bus
from mjnav.msgs import msg_class, ros
from mjnav.msgs import uav as uav_msgs
from mjnav.services.flight_controller import FlightControllerService
from tests.services.harness import Harness

HOVER_RAD_S = 537.1  # sqrt(m g / (4 k_f)) of the default vehicle


def _mocap(t: float, z: float) -> object:
    return uav_msgs.odometry3d(t, "map", "base_link", [0.0, 0.0, z], [1.0, 0.0, 0.0, 0.0], [0.0] * 3, [0.0] * 3)


@pytest.mark.e2e
def test_arming_offboard_failsafe_and_landing(peer: Callable[..., Bus]) -> None:
    h = Harness(FlightControllerService, peer, ("rotor_cmd", "flight_state"), rate_hz=50.0)
    fc = h.service
    h.send("arm", uav_msgs.boolean(True))
    h.step(0.0, {"rotor_cmd": 1})
    assert fc.state == "disarmed"  # refused: no state estimate yet
    assert not np.any(h.received["rotor_cmd"][-1].velocity)
    h.send("mocap", _mocap(0.0, 0.062))
    h.step(0.02)
    h.send("arm", uav_msgs.boolean(True))
    h.step(0.04)
    assert fc.state == "armed"
    h.step(0.06, {"rotor_cmd": 4})
    np.testing.assert_allclose(h.received["rotor_cmd"][-1].velocity, 200.0)  # idle
    h.send("setpoint", uav_msgs.pose_stamped3d(0.06, "map", [0.0, 0.0, 1.0]))
    h.step(0.08)
    assert fc.state == "offboard"
    h.step(0.10, {"rotor_cmd": 6})
    assert np.all(np.asarray(h.received["rotor_cmd"][-1].velocity) > HOVER_RAD_S)  # climbing
    # proof of life: the last setpoint arrived at 0.08 s; at 0.58 s it is 0.5 s old
    t = 0.10
    while t < 0.56 - 1e-9:
        t += 0.02
        h.send("mocap", _mocap(t, 0.3))
        h.step(t)
        assert fc.state == "offboard", t
    h.step(0.58)
    assert fc.state == "failsafe_land"
    # descends over the spot and disarms once on the ground and still for a second
    t = 0.58
    while t < 3.0:
        t += 0.02
        h.send("mocap", _mocap(t, 0.062))
        h.step(t)
    assert fc.state == "disarmed"
    assert "failsafe_land" in [m.data for m in h.received["flight_state"]]


def test_arm_false_lands_a_flying_vehicle_and_disarms_a_landed_one(peer: Callable[..., Bus]) -> None:
    h = Harness(FlightControllerService, peer, ("flight_state",), rate_hz=50.0)
    fc = h.service
    h.send("mocap", _mocap(0.0, 0.062))
    h.step(0.0)
    h.send("arm", uav_msgs.boolean(True))
    h.step(0.02)
    h.send("arm", uav_msgs.boolean(False))
    h.step(0.04)
    assert fc.state == "disarmed"
    h.send("arm", uav_msgs.boolean(True))
    h.step(0.06)
    h.send("trajectory", uav_msgs.trajectory("map", [0.1, 1.0], [[0.0, 0.0, 0.062], [0.0, 0.0, 1.0]]))
    h.step(0.08)
    assert fc.state == "offboard"
    h.send("mocap", _mocap(0.1, 1.0))
    h.send("arm", uav_msgs.boolean(False))
    h.step(0.10)
    assert fc.state == "landing"


@pytest.mark.e2e
def test_a_peers_output_of_the_same_step_waits_for_the_next_step(peer: Callable[..., Bus]) -> None:
    # In lockstep the INS's estimate and the flight client's trajectory of step t reach the controller before or
    # after clock t as the router happens to schedule them; a step at t must use what was made before t.
    h = Harness(FlightControllerService, peer, ("flight_state",), rate_hz=50.0, state_source="ins")
    fc = h.service
    h.send("imu", ros.imu(0.0, "imu", [0.0, 0.0, 0.0, 1.0], [0.0] * 3, [0.0, 0.0, 9.81]))
    h.send("ins_odom", _mocap(0.04, 0.062))  # made at the step at 0.04 s
    h.send("ins_odom", _mocap(0.06, 1.0))  # the INS's step at 0.06 s, arrived before the clock
    h.step(0.06)
    assert fc.x is not None and fc.x[2] == pytest.approx(-0.062)  # NED down of the 0.04 s estimate
    h.send("arm", uav_msgs.boolean(True))
    h.step(0.08)
    assert fc.x[2] == pytest.approx(-1.0)  # now the 0.06 s estimate
    assert fc.state == "armed"
    h.send("trajectory", uav_msgs.trajectory("map", [0.2, 1.0], [[0.0, 0.0, 1.0], [0.0, 0.0, 1.5]], t_s=0.1))
    h.step(0.1)  # the flight client's trajectory of this step: not yet
    assert fc.state == "armed"
    h.step(0.12)
    assert fc.state == "offboard"


def _odom(t: float, x: float, y: float, z: float) -> object:
    return uav_msgs.odometry3d(t, "map", "base_link", [x, y, z], [1.0, 0.0, 0.0, 0.0], [0.0] * 3, [0.0] * 3)


def _ins_health(t: float, level: int) -> object:
    status = ros.diagnostic_status(level, "ins", "lost" if level == 2 else "ok", {})
    return msg_class("diagnostic_msgs/msg/DiagnosticArray")(header=ros.header(t, "map"), status=[status])


def _ins_tick(h: Harness, t: float, pos: tuple[float, float, float], level: int = 0) -> None:
    """The INS's output of the step before ``t`` (estimate and health) and the IMU sample at ``t``; step at t."""
    h.send("imu", ros.imu(t, "imu", [0.0, 0.0, 0.0, 1.0], [0.0] * 3, [0.0, 0.0, 9.80665]))
    h.send("ins_health", _ins_health(t - 0.02, level))
    h.send("ins_odom", _odom(t - 0.02, *pos))
    h.step(t)


def _ticks(t0: float, t1: float) -> list[float]:
    return [round(t0 + 0.02 * k, 6) for k in range(round((t1 - t0) / 0.02) + 1)]


def test_position_lost_holds_altitude_then_descends_and_lands(peer: Callable[..., Bus]) -> None:
    h = Harness(
        FlightControllerService, peer, ("flight_state",), rate_hz=50.0, state_source="ins", position_loss_hold_s=0.5
    )
    fc = h.service
    _ins_tick(h, 0.02, (0.0, 0.0, 0.062), level=2)
    h.send("arm", uav_msgs.boolean(True))
    _ins_tick(h, 0.04, (0.0, 0.0, 0.062), level=2)
    assert fc.state == "disarmed"  # refused: the INS says its position is lost
    _ins_tick(h, 0.06, (0.0, 0.0, 0.062))
    h.send("arm", uav_msgs.boolean(True))
    _ins_tick(h, 0.08, (0.0, 0.0, 0.062))
    assert fc.state == "armed"
    h.send("setpoint", uav_msgs.pose_stamped3d(0.08, "map", [0.0, 0.0, 1.5]))
    _ins_tick(h, 0.10, (0.0, 0.0, 1.5))
    assert fc.state == "offboard"
    # 3 m off the setpoint: in offboard the position loop pulls hard
    _ins_tick(h, 0.12, (3.0, 0.0, 1.5))
    assert abs(fc.ctl.accel_sp[1]) > 2.0  # NED east
    # the INS's health turns ERROR (its estimate of 0.12 s): the hold starts at once, over where the vehicle was
    h.send("setpoint", uav_msgs.pose_stamped3d(0.12, "map", [0.0, 0.0, 1.5]))
    _ins_tick(h, 0.14, (3.0, 0.0, 1.5), level=2)
    assert fc.state == "failsafe_hold"
    for t in _ticks(0.16, 0.62):
        h.send("setpoint", uav_msgs.pose_stamped3d(t - 0.02, "map", [0.0, 0.0, 1.5]))  # ignored now
        _ins_tick(h, t, (5.0, 1.0, 1.5), level=2)  # the dead-reckoned estimate wanders off: no pull back
        assert fc.state == "failsafe_hold", t
        assert np.all(np.abs(fc.ctl.accel_sp[0:2]) < 1e-9)  # no horizontal command: zero velocity held
    _ins_tick(h, 0.64, (5.0, 1.0, 1.5), level=2)
    assert fc.state == "failsafe_descend"  # position_loss_hold_s after 0.14 s
    _ins_tick(h, 0.66, (5.0, 1.0, 1.5), level=2)
    assert fc.ctl.accel_sp[2] > 0.5  # NED down: the descent setpoint (0.3 m/s) pulls the vehicle down
    for t in _ticks(0.68, 1.5):
        _ins_tick(h, t, (5.0, 1.0, 0.062), level=2)
    assert fc.state == "disarmed"
    states = [m.data for m in h.received["flight_state"]]
    assert states.index("failsafe_hold") < states.index("failsafe_descend") < len(states)


def test_a_landing_without_position_goes_straight_to_the_descent(peer: Callable[..., Bus]) -> None:
    h = Harness(FlightControllerService, peer, ("flight_state",), rate_hz=50.0, state_source="ins")
    fc = h.service
    _ins_tick(h, 0.02, (0.0, 0.0, 0.062))
    h.send("arm", uav_msgs.boolean(True))
    _ins_tick(h, 0.04, (0.0, 0.0, 0.062))
    h.send("setpoint", uav_msgs.pose_stamped3d(0.04, "map", [0.0, 0.0, 1.5]))
    _ins_tick(h, 0.06, (0.0, 0.0, 1.5))
    h.send("arm", uav_msgs.boolean(False))
    _ins_tick(h, 0.08, (0.0, 0.0, 1.5))
    assert fc.state == "landing"
    _ins_tick(h, 0.10, (0.0, 0.0, 1.5), level=2)
    assert fc.state == "failsafe_descend"


@pytest.mark.parametrize("action", ["return", "land"])
def test_leaving_the_geofence_returns_home_or_lands(peer: Callable[..., Bus], action: str) -> None:
    h = Harness(
        FlightControllerService, peer, ("flight_state",), rate_hz=50.0, geofence_radius_m=2.0, geofence_action=action
    )
    fc = h.service
    h.send("mocap", _odom(0.0, 2.5, 0.0, 0.062))
    h.step(0.0)
    h.send("arm", uav_msgs.boolean(True))
    h.step(0.02)
    assert fc.state == "disarmed"  # refused outside the fence
    h.send("mocap", _odom(0.02, 0.5, 0.0, 0.062))
    h.step(0.04)
    h.send("arm", uav_msgs.boolean(True))
    h.step(0.06)
    assert fc.state == "armed"
    h.send("setpoint", uav_msgs.pose_stamped3d(0.06, "map", [3.0, 0.0, 1.0]))  # beyond the fence
    h.send("mocap", _odom(0.06, 1.9, 0.0, 1.0))
    h.step(0.08)
    assert fc.state == "offboard"
    h.send("setpoint", uav_msgs.pose_stamped3d(0.08, "map", [3.0, 0.0, 1.0]))
    h.send("mocap", _odom(0.08, 2.1, 0.0, 1.0))
    h.step(0.10)
    if action == "land":
        assert fc.state == "failsafe_land"
        return
    assert fc.state == "failsafe_return"
    ref = fc._return
    assert ref is not None
    # over the arming position (0.5 m east, ENU x = NED east), at the altitude it had, in (1.6 m / 1 m/s) s
    np.testing.assert_allclose(ref.at(ref.t1)[0], [0.0, 0.5, -1.0], atol=1e-9)
    assert ref.t1 - ref.t0 == pytest.approx(1.6)
    for t in _ticks(0.12, ref.t1 + 1.0 - 0.02):  # flown as the reference says, then a second over home
        pos = ref.at(t)[0]
        h.send("mocap", _odom(t, pos[1], pos[0], -pos[2]))
        h.step(t)
        assert fc.state == "failsafe_return", t
    t = round(ref.t1 + 1.0, 6)
    h.send("mocap", _odom(t, 0.5, 0.0, 1.0))
    h.step(t)
    assert fc.state == "failsafe_land"
    assert fc._land_start is not None
    np.testing.assert_allclose(fc._land_start[1], [0.0, 0.5, -1.0], atol=1e-6)  # landing over home


def test_the_ceiling_is_a_fence_too(peer: Callable[..., Bus]) -> None:
    h = Harness(FlightControllerService, peer, ("flight_state",), rate_hz=50.0, geofence_max_altitude_m=3.0)
    fc = h.service
    h.send("mocap", _odom(0.0, 0.0, 0.0, 0.062))
    h.step(0.0)
    h.send("arm", uav_msgs.boolean(True))
    h.step(0.02)
    h.send("setpoint", uav_msgs.pose_stamped3d(0.02, "map", [0.0, 0.0, 5.0]))
    h.step(0.04)
    assert fc.state == "offboard"
    h.send("setpoint", uav_msgs.pose_stamped3d(0.04, "map", [0.0, 0.0, 5.0]))
    h.send("mocap", _odom(0.04, 0.0, 0.0, 3.2))
    h.step(0.06)
    assert fc.state == "failsafe_return"
    assert fc._return is not None
    np.testing.assert_allclose(fc._return.at(fc._return.t1)[0], [0.0, 0.0, -2.7], atol=1e-9)  # below the ceiling


def test_the_attitude_comes_from_the_newest_plausible_imu_sample(peer: Callable[..., Bus]) -> None:
    h = Harness(FlightControllerService, peer, ("flight_state",), rate_hz=50.0, state_source="ins")
    fc = h.service
    level, rolled = [0.0, 0.0, 0.0, 1.0], [np.sin(np.pi / 8), 0.0, 0.0, np.cos(np.pi / 8)]  # xyzw; 45° roll

    def imu(t: float, q: list[float]) -> object:
        return ros.imu(t, "imu", q, [0.0] * 3, [0.0, 0.0, 9.80665])  # at rest

    h.send("imu", imu(0.0, level))
    h.send("imu", imu(0.02, level))
    h.send("ins_odom", _odom(0.0, 0.0, 0.0, 0.062))
    h.step(0.02)
    h.send("imu", imu(0.04, level))
    h.send("imu", imu(0.04, rolled))  # a second sample with the same stamp, arriving later
    h.send("imu", imu(0.0, rolled))  # an old one
    h.send("imu", imu(0.06, rolled))  # one from the next step, arriving before the real one
    h.step(0.04)
    assert fc.x is not None
    q_level = quat_enu_flu_to_ned_frd([1.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(fc.x[6:10], q_level, atol=1e-12)
    assert fc.imu.check.rejected["stamp_not_increasing"] == 2
    # the early one waited for its step, where the accelerometer at rest denies its attitude; the real one is taken
    h.send("imu", imu(0.06, level))
    h.step(0.06)
    assert fc.imu.check.rejected["gravity"] == 1 and fc.imu.check.accepted == 4
    np.testing.assert_allclose(fc.x[6:10], q_level, atol=1e-12)
