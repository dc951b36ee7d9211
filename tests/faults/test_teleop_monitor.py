"""Teleop under the collision monitor (issue 31): a joystick held at full speed toward a wall, in lockstep.

The sim runs as its own process (``mjnav run sim``) on loopback Zenoh; this test is its one lockstep participant and
publishes ``cmd_vel_teleop`` every 50 ms of sim time, as a held joystick does. Without the monitor the robot drives
into the wall (the failure issue 31 measured); with it, it stops at least 0.05 m from it. Everything is asserted on
sim time and on the true pose.
"""

from __future__ import annotations

import math
import subprocess
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest

from mjnav.bus import Bus, wait_until
from mjnav.msgs import ros
from mjnav.runtime.participant import LockstepParticipant
from mjnav.sim.truth import FootprintClearance
from tests.conftest import REPO, stop_process

pytestmark = pytest.mark.e2e  # a sim process


class _Joystick(LockstepParticipant):
    """Holds one twist on ``cmd_vel_teleop``, sent at every lockstep step; records the true poses."""

    def __init__(self, bus: Bus, v_mps: float, omega_radps: float) -> None:
        self._init_participant(bus, "teleop", 0.05)
        self._pub = bus.publisher("cmd_vel_teleop")
        self._twist = ros.twist(v_mps, omega_radps)
        self.truth: list[tuple[float, float, float]] = []
        bus.subscribe("truth", callback=self._on_truth)
        self._subscribe_clock()
        self._participate()

    def _on_truth(self, msg: Any) -> None:
        self.truth.append((ros.seconds(msg.header.stamp), msg.pose.position.x, msg.pose.position.y))

    def _step(self, t: float) -> None:
        self._pub.put(self._twist)


@contextmanager
def _sim(router_endpoint: str, *settings: str) -> Iterator[None]:
    cmd = [sys.executable, "-m", "mjnav", "run", "sim", "--connect", router_endpoint, "--set", "world=rooms",
           "--set", "rtf=0", "--set", 'lockstep_participants=["teleop"]']  # fmt: skip
    for s in settings:
        cmd += ["--set", s]
    proc = subprocess.Popen(cmd, cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    try:
        yield
    finally:
        stop_process(proc)


@pytest.mark.parametrize("monitor", [True, False])
def test_teleop_at_full_speed_toward_a_wall_stops_short_of_it(
    monitor: bool, router_endpoint: str, peer: Callable[..., Bus]
) -> None:
    clearance = FootprintClearance("rooms").clearance_m
    with _sim(router_endpoint, f"collision_monitor={'true' if monitor else 'false'}"):
        bus = peer()
        states: list[Any] = []
        bus.subscribe("collision_monitor", callback=states.append, immediate=True)
        status = bus.subscribe("sim_status")
        joystick = _Joystick(bus, 0.5, 0.0)  # from (-3.5, -3.5) along +x: the wall at x = 0 is 3.25 m away
        assert wait_until(lambda: joystick.truth and joystick.truth[-1][0] >= 15.0, 180.0), "sim time stalled"
        assert status.wait(30.0, lambda s: ros.seconds(s.header.stamp) >= 15.0) is not None
        collisions = status.latest().collisions
    closest = min(clearance(x, y) for _, x, y in joystick.truth)
    driven = joystick.truth[-1][1] - joystick.truth[0][1]
    assert driven > 2.5  # it drove the whole way toward the wall
    if not monitor:
        assert collisions > 0 and closest < 0.0  # nothing below teleop: into the wall
        return
    assert collisions == 0
    assert closest >= 0.05, f"stopped {closest:.3f} m from the wall"
    # Held forward against the wall for 5 s: it stands (the lidar's noise may let it creep a few millimetres).
    held = [x for t, x, _ in joystick.truth if t >= 10.0]
    assert max(held) - min(held) < 0.01, " ".join(f"{x:.4f}" for x in held)
    assert wait_until(lambda: states and states[-1].level == 2, 10.0)  # ERROR: stopped
    values = ros.diagnostic_values(states[-1])
    assert values["source"] == "teleop" and values["action"] in ("stop", "approach")


class _Script(_Joystick):
    """A joystick that follows a script: (until sim time s, v m/s, ω rad/s) rows, then the last row's twist."""

    def __init__(self, bus: Bus, script: list[tuple[float, float, float]]) -> None:
        self._script = script
        self.carts: list[tuple[float, float, float]] = []  # (sim time, x, y) of the cart
        bus.subscribe("obstacles", callback=self._on_obstacles)
        super().__init__(bus, script[0][1], script[0][2])

    def _on_obstacles(self, msg: Any) -> None:
        for tf in msg.transforms:
            if tf.child_frame_id == "cart":
                p = tf.transform.translation
                self.carts.append((ros.seconds(tf.header.stamp), p.x, p.y))

    def _step(self, t: float) -> None:
        row = next((r for r in self._script if t < r[0]), self._script[-1])
        self._pub.put(ros.twist(row[1], row[2]))


def test_teleop_at_full_speed_across_the_warehouse_stops_for_the_crossing_cart(
    router_endpoint: str, peer: Callable[..., Bus]
) -> None:
    """North up the west aisle to the cross aisle, a right turn, then full speed east along it: the cart (1.0 m x
    0.7 m, sliding along x = 0 at up to 0.79 m/s) crosses the robot's way as it arrives; the robot stops short of it
    and goes on once it has passed, and ends held against the east wall."""
    with _sim(router_endpoint, "world=warehouse"):
        bus = peer()
        status = bus.subscribe("sim_status")
        turn = math.pi / 2  # at 1 rad/s
        joystick = _Script(bus, [(6.0, 0.5, 0.0), (6.0 + turn, 0.0, -1.0), (math.inf, 0.5, 0.0)])
        assert wait_until(lambda: joystick.truth and joystick.truth[-1][0] >= 40.0, 300.0), "sim time stalled"
        assert status.wait(30.0, lambda s: ros.seconds(s.header.stamp) >= 40.0) is not None
        collisions = status.latest().collisions
    static = FootprintClearance("warehouse").clearance_m
    radius = 0.19
    carts = np.asarray(joystick.carts)
    closest_cart = math.inf
    for t, x, y in joystick.truth:
        k = int(np.argmin(np.abs(carts[:, 0] - t)))
        qx, qy = abs(x - carts[k, 1]) - 0.5, abs(y - carts[k, 2]) - 0.35  # the cart's box, axis-aligned
        closest_cart = min(closest_cart, math.hypot(max(qx, 0.0), max(qy, 0.0)) + min(max(qx, qy), 0.0) - radius)
    assert collisions == 0
    assert closest_cart >= 0.05, f"{closest_cart:.3f} m from the cart"
    assert min(static(x, y) for _, x, y in joystick.truth) >= 0.05
    assert closest_cart < 0.5  # the cart did cross in front of it
    assert joystick.truth[-1][1] > 7.0  # it went on after the cart, to the east wall
