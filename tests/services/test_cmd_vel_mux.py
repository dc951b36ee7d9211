"""The sim's velocity mux: ``cmd_vel_teleop`` overrides navigation's ``cmd_vel`` while fresh (sim time), navigation
resumes after ``teleop_timeout_s`` of silence."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from mjnav.bus import Bus, Subscription, wait_until
from mjnav.msgs import ros
from mjnav.services.sim import SimBridge, SimConfig

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers


class _Wheels:
    """Stands in for the Simulator: records the commands the bridge applies."""

    moving_body_names: tuple[str, ...] = ()
    lidar_config = None  # no lidar (the bridge reads the scan period from the simulator's model lidar)

    def __init__(self) -> None:
        self.commands: list[tuple[float, float]] = []

    def set_command(self, v_mps: float, omega_radps: float) -> None:
        self.commands.append((v_mps, omega_radps))


def test_teleop_overrides_navigation_while_fresh(peer: Callable[..., Bus]) -> None:
    wheels = _Wheels()
    sim_bus = peer()
    bridge = SimBridge(wheels, sim_bus, SimConfig(world="empty", teleop_timeout_s=0.5, collision_monitor=False))
    me = peer()
    pubs = {name: me.publisher(name) for name in ("cmd_vel", "cmd_vel_teleop")}
    subs = {d.key.rsplit("/", 1)[1]: d for d in sim_bus._declared if isinstance(d, Subscription) and "cmd_vel" in d.key}

    def send(name: str, v: float, w: float) -> None:
        assert pubs[name].wait_for_subscribers(10.0)
        before = subs[name].count
        pubs[name].put(ros.twist(v, w))
        assert wait_until(lambda: subs[name].count > before, 10.0)

    send("cmd_vel", 0.4, 0.0)
    bridge.apply_command(1.0)
    assert wheels.commands[-1] == (0.4, 0.0) and not bridge.teleop_active
    send("cmd_vel_teleop", 0.0, 1.2)
    send("cmd_vel", 0.4, 0.1)
    bridge.apply_command(1.01)
    assert wheels.commands[-1] == (0.0, 1.2) and bridge.teleop_active  # teleop wins over a simultaneous command
    send("cmd_vel", 0.4, 0.2)
    bridge.apply_command(1.3)
    send("cmd_vel", 0.4, 0.3)
    bridge.apply_command(1.51)  # 0.5 s after the teleop command: still held
    assert wheels.commands[-1] == (0.0, 1.2) and len(wheels.commands) == 2
    send("cmd_vel", 0.4, 0.4)
    bridge.apply_command(1.52)  # teleop silent for longer than 0.5 s: navigation's newest command drives
    assert wheels.commands[-1] == (0.4, 0.4) and not bridge.teleop_active
    send("cmd_vel_teleop", -0.1, 0.0)
    bridge.apply_command(1.6)
    assert wheels.commands[-1] == (-0.1, 0.0) and bridge.teleop_active
