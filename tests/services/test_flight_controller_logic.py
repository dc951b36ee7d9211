"""Flight-controller logic on a real in-process bus, stepped by the test at chosen sim times: arming, offboard from a
PoseStamped setpoint, the 0.5 s failsafe, a commanded landing."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from mjnav.bus import Bus
from mjnav.msgs import ros
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
