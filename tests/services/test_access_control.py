"""Access control with the real services: the rights table allows what each service really declares, and the
whole stack runs under ``mjnav up --secure`` while an identity outside the rules tries to end the goal, freeze the
clock, poison the costmap and drive the robot."""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import zenoh

from mjnav.bus import Bus, BusConfig, Publisher, wait_until
from mjnav.bus.acl import allowed, grants
from mjnav.bus.certs import make_certificates
from mjnav.bus.config import tls_files
from mjnav.msgs import from_dict, msg_class, ros
from mjnav.msgs.topics import OPERATOR
from mjnav.runtime.mission import MissionClient
from mjnav.runtime.stack import load_stack, services_dir
from tests.services.test_navigation import RTF, SERVICES, up_process

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

#: Settings that make every service declare everything it can (the warehouse has moving obstacles) and start no
#: server.
_SETTINGS = {"sim": {"world": "warehouse"}, "viz": {"serve": False}, "uav_viz": {"serve": False}}
STATUS = msg_class("mjnav_msgs/msg/GoalStatus")


@pytest.mark.parametrize("stack_file", ["stack.toml", "uav_stack.toml"])
def test_every_publisher_and_endpoint_a_service_declares_is_allowed_by_the_rights_table(
    peer: Callable[..., Bus], stack_file: str
) -> None:
    stack = load_stack(services_dir() / stack_file)
    table = grants(stack.namespace, stack.names())
    for spec in stack.services:
        bus = peer(stack.namespace)
        service = spec.load_class()(spec.load_config(_SETTINGS.get(spec.name)), bus, logging.getLogger("test"))
        service.configure()
        service.activate()
        try:
            keys = [d.key for d in bus._declared if isinstance(d, Publisher)]
            served = [str(d.key_expr) for d in bus._declared if isinstance(d, zenoh.Queryable)]
            denied = [k for k in keys if not allowed(table, spec.name, "put", k)]
            denied += [k for k in served if not allowed(table, spec.name, "serve", k)]
            assert not denied, f"{spec.name} declares {denied}: add them to PUBLISH_RIGHTS / SERVE_RIGHTS"
            assert keys or spec.name.endswith("viz"), f"{spec.name} declared no publisher: the check saw nothing"
        finally:
            service.deactivate()


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("certs")
    make_certificates(out, [*load_stack().names(), OPERATOR, "intruder"])
    return out


class _Intruder:
    """A client with a valid certificate outside the rules. Each goal status it sees (on ``listen``) is answered
    (on ``send``: a latched key must not be published from a callback of its own subscription in one session) with
    a forged REACHED for the same goal, a lethal costmap, a clock at 2³¹−1 s and a full-speed spin command."""

    def __init__(self, listen: Bus, send: Bus) -> None:
        self.sent = 0
        self._pubs = {name: send.publisher(name) for name in ("goal_status", "costmap", "clock", "cmd_vel")}
        grid = {"info": {"resolution": 0.05, "width": 400, "height": 400, "origin": {"orientation": {"w": 1.0}}}}
        grid["info"]["origin"]["position"] = {"x": -10.0, "y": -10.0}
        self._costmap = from_dict("nav_msgs/msg/OccupancyGrid", {**grid, "data": [100] * 160_000})
        self._lock = threading.Lock()
        listen.subscribe("goal_status", callback=self._on_status)

    def _on_status(self, status: Any) -> None:
        if status.state in (STATUS.STATE_REACHED, STATUS.STATE_FAILED, STATUS.STATE_CANCELED):
            return
        forged = from_dict("mjnav_msgs/msg/GoalStatus", {"goal_id": int(status.goal_id), "state": 4})
        forged.goal = status.goal
        forged.header = status.header
        with self._lock:
            self._pubs["goal_status"].put(forged)
            self._pubs["costmap"].put(self._costmap)
            self._pubs["clock"].put(from_dict("rosgraph_msgs/msg/Clock", {"clock": {"sec": 2**31 - 1}}))
            self._pubs["cmd_vel"].put(ros.twist(0.5, 2.0))
            self.sent += 4


def test_the_stack_runs_under_secure_and_an_outsider_cannot_end_the_goal_or_move_the_robot(certs: Path) -> None:
    goal = (3.8, 2.2)
    with up_process("--secure", str(certs), "--set", f"sim.rtf={RTF}") as (port, proc, lines):
        endpoint = f"tls/127.0.0.1:{port}"
        operator = Bus.open(BusConfig(mode="client", connect=(endpoint,), listen=(), **tls_files(certs, OPERATOR)))
        intruder_config = BusConfig(mode="client", connect=(endpoint,), listen=(), **tls_files(certs, "intruder"))
        intruder_bus, intruder_out = Bus.open(intruder_config), Bus.open(intruder_config)
        try:
            client = MissionClient(operator, name=OPERATOR)  # the sim announces the robot's start
            assert wait_until(lambda: set(SERVICES) <= set(operator.alive_services(0.5)), 180.0), "".join(lines)[-3000:]
            assert client.truth.wait(60.0) is not None
            mapper_status = operator.subscribe("status", service="mapper")
            intruder = _Intruder(intruder_bus, intruder_out)
            outcome = client.run_goal(*goal, timeout_s=200.0, wall_timeout_s=300.0)
            assert intruder.sent > 0, "the intruder never saw a goal status: the test proved nothing"
            assert outcome.result == "reached", outcome
            # Reached for real: the robot is at the goal (a forged REACHED would have ended the goal where it stood).
            final = client.final_pose
            assert final is not None and math.hypot(final.x - goal[0], final.y - goal[1]) < 0.3, final
            assert outcome.time_s > 5.0  # sim seconds: driving there took time, the goal did not end at once
            assert client.collisions() == 0
            # The forged clock froze nothing: the mapper keeps stepping on sim time.
            first = mapper_status.wait(10.0)
            assert first is not None
            assert mapper_status.wait(10.0, lambda s: s.steps > first.steps) is not None
            assert proc.poll() is None
        finally:
            intruder_out.close()
            intruder_bus.close()
            operator.close()
    text = "".join(lines)
    assert "lockstep: sim time starts with" in text and "restarting" not in text
    assert "clock went back" not in text
