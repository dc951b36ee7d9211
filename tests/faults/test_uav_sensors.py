"""UAV sensor faults and forged inputs at unit level, on a real in-process bus: the UAV sim's GPS fault windows and
its rotor-command rule, the INS's gates, IMU checks and health, the flight controller's IMU intake. Sim time is
chosen by the test; every assertion is on sim time and sim-time figures."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from mjnav.aerial import geodetic_to_enu
from mjnav.bus import Bus, wait_until
from mjnav.msgs import ros
from mjnav.msgs import uav as uav_msgs
from mjnav.services.uav_sim import UavBridge, UavSimConfig, in_windows
from mjnav.sim.uav import UavSimulator

ROTORS = ("rotor0", "rotor1", "rotor2", "rotor3")


def _bridge(peer: Callable[..., Bus], **config: Any) -> tuple[UavBridge, Bus]:
    sim = UavSimulator("field", seed=4)
    return UavBridge(sim, peer("uav0"), UavSimConfig(**config)), peer("uav0")


def _fixes(peer: Callable[..., Bus], **config: Any) -> list[tuple[float, np.ndarray]]:
    """(stamp, ENU position) of every fix 3 s of a UAV sim on the pad publish."""
    bridge, world = _bridge(peer, **config)
    got: list[Any] = []
    world.subscribe("gps", callback=got.append)
    clock = world.subscribe("clock")
    bridge.advance(3.0)
    assert clock.wait(10.0, lambda c: ros.seconds(c.clock) >= 3.0 - 1e-9) is not None
    assert wait_until(lambda: len(got) >= 1, 10.0)
    o = bridge.sim.origin
    return [
        (
            ros.seconds(m.header.stamp),
            np.array(geodetic_to_enu(m.latitude, m.longitude, m.altitude, o.lat_deg, o.lon_deg, o.alt_m)),
        )
        for m in got
    ]


@pytest.mark.e2e
def test_gps_dropout_and_glitch_windows_of_the_uav_sim(peer: Callable[..., Bus]) -> None:
    normal = _fixes(peer)
    faulty = _fixes(peer, gps_dropout_s=(1.0, 1.5, 2.0, 2.2), gps_glitch_s=(0.55, 0.65), gps_glitch_m=(55.0, 0.0, -3.0))
    stamps = [round(t, 6) for t, _ in normal]
    assert len(stamps) >= 28  # 10 Hz, published 0.15 s after they are taken
    kept = [t for t in stamps if not (1.0 <= t < 1.5 or 2.0 <= t < 2.2)]
    assert [round(t, 6) for t, _ in faulty] == kept
    by_stamp = {round(t, 6): p for t, p in normal}
    for t, p in faulty:
        offset = np.array([55.0, 0.0, -3.0]) if 0.55 <= t < 0.65 else np.zeros(3)
        np.testing.assert_allclose(p - by_stamp[round(t, 6)], offset, atol=1e-6)  # the same noise, plus the glitch


def test_fault_windows_are_validated() -> None:
    assert in_windows(1.0, (1.0, 2.0)) and not in_windows(2.0, (1.0, 2.0)) and not in_windows(0.5, ())
    for bad in ((1.0,), (2.0, 1.0), (0.0, math.nan)):
        with pytest.raises(ValueError):
            UavSimConfig(gps_dropout_s=bad)
    with pytest.raises(ValueError):
        UavSimConfig(gps_glitch_m=(math.inf, 0.0, 0.0))


@pytest.mark.e2e
def test_the_uav_sim_takes_no_stale_or_future_rotor_command(peer: Callable[..., Bus]) -> None:
    bridge, world = _bridge(peer)
    pub = world.publisher("rotor_cmd")
    assert pub.wait_for_subscribers(10.0)

    def send(stamp: float, speed: float) -> None:
        before = bridge.commands_refused
        taken = bridge._command
        pub.put(ros.joint_state(stamp, ROTORS, np.zeros(4), np.full(4, speed)))
        assert wait_until(lambda: bridge.commands_refused > before or bridge._command is not taken, 10.0)

    bridge.advance(1.0)
    send(1.0, 300.0)  # the flight controller's command of the step at 1 s
    send(0.0, 2000.0)  # older than the one taken: refused
    send(5.0, 2000.0)  # from the future: refused
    assert bridge.commands_refused == 2
    bridge.advance(1.02)
    np.testing.assert_allclose(bridge.sim.rotor_speed_cmd, 300.0)
    send(1.02, 400.0)
    bridge.advance(1.04)
    np.testing.assert_allclose(bridge.sim.rotor_speed_cmd, 400.0)
