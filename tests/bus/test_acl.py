"""Access control on a real Zenoh router with mutual TLS: who may connect, and whose messages reach subscribers.

Delivery is checked without sleeps: after its messages, a sender calls an endpoint served by the receiving session
(``config/<receiver>``). The query travels the sender's link and the router's link to the receiver at the priority
of the messages before it, and the receiver's subscriptions run in Zenoh's network thread, so when the reply is
back, every message the router forwarded has been counted.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh

from mjnav.bus import Bus, BusConfig, BusConfigError, NoReply, wait_until
from mjnav.bus.acl import access_control, allowed, grants, rights_markdown, secure_router_config
from mjnav.bus.certs import make_certificates
from mjnav.bus.config import tls_files
from mjnav.msgs import TOPICS, encode, from_dict, msg_class, validate
from mjnav.msgs.topics import OPERATOR, OWN, PUBLISH_RIGHTS, lockstep_key
from mjnav.runtime.stack import load_stack, services_dir
from tests.conftest import REPO, free_port

SERVICES = load_stack().names()
INTRUDER = "intruder"
#: Receives everything in these tests and serves the fence endpoint ``config/<RECEIVER>``.
RECEIVER = "smoother"
#: Valid-but-forged messages per protected key and unauthorised identity in the fuzz test.
FORGED_PER_KEY = 400


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("certs")
    make_certificates(out, [*SERVICES, OPERATOR, INTRUDER])
    return out


@pytest.fixture(scope="module")
def secure_router(certs: Path) -> Iterator[str]:
    """A router on mutual TLS with the shipped stack's access control; yields its endpoint."""
    endpoint = f"tls/127.0.0.1:{free_port()}"
    router = Bus.open(secure_router_config(certs, [endpoint], "robot0", SERVICES))
    yield endpoint
    router.close()


@pytest.fixture
def client(certs: Path, secure_router: str) -> Iterator[Callable[[str], Bus]]:
    """Opens client sessions on the secure router with the certificate of an identity."""
    opened: list[Bus] = []

    def make(identity: str) -> Bus:
        files = tls_files(certs, identity)
        bus = Bus.open(BusConfig(mode="client", connect=(secure_router,), listen=(), **files))
        opened.append(bus)
        return bus

    yield make
    for bus in reversed(opened):
        bus.close()


def _refused(config: Any) -> bool:
    """Whether a session with ``config`` (connect retries bounded) fails to open."""
    config.insert_json5("connect/timeout_ms", "2000")
    config.insert_json5("connect/exit_on_failure", "true")
    try:
        zenoh.open(config).close()
    except zenoh.ZError:
        return True
    return False


class Receiver:
    """A session that subscribes to every topic, counts messages per topic, and serves the fence endpoint."""

    def __init__(self, bus: Bus) -> None:
        self.bus = bus
        self.count = dict.fromkeys(TOPICS, 0)
        self.last: dict[str, Any] = {}
        for name, row in TOPICS.items():
            bus.subscribe(name, callback=self._counter(name), service="*" if row.per_service else None)
        string = msg_class("std_msgs/msg/String")
        bus.serve("config", lambda _req: string(data="{}"), service=RECEIVER)

    def _counter(self, name: str) -> Callable[[Any], None]:
        def on_msg(msg: Any) -> None:
            self.count[name] += 1
            self.last[name] = msg

        return on_msg


def _fence(sender: Bus) -> None:
    """Returns once everything ``sender`` published before has been delivered to (or dropped before) the
    receiver (see the module docstring)."""
    assert sender.call("config", service=RECEIVER, timeout_s=10.0).data == "{}"


def _forged(name: str, rng: np.random.Generator) -> Any:
    """A valid message for topic ``name`` meant to do harm: far-future clock, REACHED/FAILED goal status, lethal
    costmap, full-speed cmd_vel, a lockstep report for another participant…"""
    pose = {"position": {"x": float(rng.normal()), "y": float(rng.normal())}, "orientation": {"w": 1.0}}
    grid = {"info": {"resolution": 0.05, "width": 8, "height": 8, "origin": {"orientation": {"w": 1.0}}}}
    by_type: dict[str, dict[str, Any]] = {
        "sensor_msgs/msg/LaserScan": {
            "range_min": 0.1,
            "range_max": 12.0,
            "ranges": [0.2] * 360,
            "angle_increment": 2 * math.pi / 360,
        },
        "nav_msgs/msg/Odometry": {"pose": {"pose": pose}},
        "geometry_msgs/msg/PoseStamped": {"header": {"frame_id": "map"}, "pose": pose},
        "nav_msgs/msg/OccupancyGrid": {**grid, "data": [100] * 64},
    }
    by_topic: dict[str, dict[str, Any]] = {
        "clock": {"clock": {"sec": int(rng.choice([2**31 - 1, 0, int(rng.integers(0, 2**31))]))}},
        "cmd_vel": {"linear": {"x": float(rng.uniform(-1, 1))}, "angular": {"z": float(rng.uniform(-2, 2))}},
        "goal_status": {
            "goal_id": int(rng.integers(0, 100)),
            "state": int(rng.choice([4, 5, 6])),
            "goal": {"pose": pose},
        },
        "lockstep": {"participant": "planner", "ready_until": {"sec": 2**31 - 1}},
        "status": {"service": "mapper", "state": 2, "steps": int(rng.integers(0, 10**6))},
        "arm": {"data": bool(rng.integers(0, 2))},
        "rotor_cmd": {"name": [f"rotor{i}" for i in range(4)], "velocity": [0.0] * 4},
    }
    msgtype = TOPICS[name].msgtype
    msg = from_dict(msgtype, by_topic.get(name, by_type.get(msgtype, {})))
    validate(msg)
    return msg


def _target(name: str, victim: str) -> str | None:
    """The service slot a forged per-service message claims (another identity's), None for plain topics."""
    return victim if TOPICS[name].per_service else None


def test_rules_cover_every_topic_and_endpoint_and_name_real_identities() -> None:
    table = grants("robot0", SERVICES, ["mission"])
    assert set(PUBLISH_RIGHTS) == set(TOPICS)
    identities = {*SERVICES, *load_stack(services_dir() / "uav_stack.toml").names(), OPERATOR, OWN}
    for name, rights in PUBLISH_RIGHTS.items():
        assert set(rights) <= identities, f"{name}: unknown identity in {rights}"
    # What the issue names: only the sim drives time, only the controller and the operator move the robot, …
    who_may = {
        n: {i for i in table if allowed(table, i, "put", TOPICS[n].key("robot0"))}
        for n in ("clock", "cmd_vel", "goal_status", "controller_feedback", "costmap", "map", "goal", "cancel")
    }
    assert who_may == {
        "clock": {"sim"},
        "cmd_vel": {"controller", OPERATOR},
        "goal_status": {"planner"},  # the planner owns every goal
        "controller_feedback": {"controller"},
        "costmap": {"mapper"},
        "map": {"slam", "mapper"},  # SLAM's map; the mapper's own with map_source = scan
        "goal": {OPERATOR},
        "cancel": {OPERATOR},
    }
    assert allowed(table, "planner", "put", "robot0/status/planner")
    assert not allowed(table, "planner", "put", "robot0/status/mapper")
    assert allowed(table, "planner", "token", "mjnav/alive/robot0/planner")
    assert not allowed(table, INTRUDER, "token", "mjnav/alive/robot0/planner")
    assert allowed(table, OPERATOR, "token", "mjnav/lockstep/robot0/mission")
    assert not allowed(table, "viz", "token", "mjnav/lockstep/robot0/mission")
    assert allowed(table, INTRUDER, "query", "robot0/config/sim")
    assert not allowed(table, INTRUDER, "query", "robot0/save_map")
    assert allowed(table, OPERATOR, "query", "robot0/save_map")
    assert allowed(table, "mapper", "serve", "robot0/save_map")
    assert not allowed(table, "sim", "serve", "robot0/save_map")
    acl = access_control("robot0", SERVICES)
    assert acl["default_permission"] == "deny"
    json.dumps(acl)  # what BusConfig hands to Zenoh


def test_readme_rights_table_is_generated_from_the_table() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    m = re.search(r"<!-- rights-table:begin -->\n(.*?)\n<!-- rights-table:end -->", readme, re.S)
    assert m, "README.md lacks the generated rights table markers"
    assert m.group(1) == rights_markdown(), "README rights table is stale: paste mjnav.bus.acl.rights_markdown()"


@pytest.mark.e2e
def test_a_client_without_a_valid_certificate_cannot_connect(certs: Path, secure_router: str, tmp_path: Path) -> None:
    files = tls_files(certs, OPERATOR)
    # TLS, the right CA, but no client certificate: the router asks for one (mutual TLS).
    assert _refused(BusConfig(mode="client", connect=(secure_router,), listen=(), tls_ca=files["tls_ca"]).to_zenoh())
    # Plain TCP to the TLS port.
    plain = secure_router.replace("tls/", "tcp/")
    assert _refused(BusConfig(mode="client", connect=(plain,), listen=()).to_zenoh())
    # A certificate of another CA (made the same way, by someone else).
    other = make_certificates(tmp_path / "other", [OPERATOR])
    stranger = tls_files(tmp_path / "other", OPERATOR)
    assert other and stranger["tls_ca"] != files["tls_ca"]
    mixed = {**stranger, "tls_ca": files["tls_ca"]}  # trusts our router, presents a foreign certificate
    assert _refused(BusConfig(mode="client", connect=(secure_router,), listen=(), **mixed).to_zenoh())
    # The same client with its own certificate connects.
    assert not _refused(BusConfig(mode="client", connect=(secure_router,), listen=(), **files).to_zenoh())


def test_tls_config_leaves_no_plain_tcp_way_in(certs: Path) -> None:
    files = tls_files(certs, "planner")
    with pytest.raises(BusConfigError, match="not tls"):
        BusConfig(mode="client", connect=("tcp/127.0.0.1:7447",), listen=(), **files)
    with pytest.raises(BusConfigError, match="tls_cert and tls_key"):
        BusConfig(mode="client", connect=(), listen=(), tls_ca=files["tls_ca"], tls_cert=files["tls_cert"])
    with pytest.raises(BusConfigError, match="router"):
        BusConfig(mode="client", connect=(), listen=(), access_control="{}", **files)
    with pytest.raises(BusConfigError, match="mjnav certs"):
        tls_files(certs, "nobody")


@pytest.mark.parametrize("forger", ["viz", INTRUDER, OPERATOR])
def test_a_wrong_identity_cannot_publish_what_is_not_its_own(client: Callable[[str], Bus], forger: str) -> None:
    rng = np.random.default_rng(11)
    receiver = Receiver(client(RECEIVER))
    bus = client(forger)
    table = grants("robot0", SERVICES)
    victims = ["clock", "cmd_vel", "goal_status", "costmap", "map", "goal", "lockstep", "status"]
    denied = [n for n in victims if not allowed(table, forger, "put", TOPICS[n].key("robot0", _target(n, "planner")))]
    assert {"clock", "goal_status", "costmap", "lockstep", "status"} <= set(denied)
    for name in denied:
        pub = bus.publisher(name, service=_target(name, "planner"))
        # The router tells the forger a subscriber exists: the messages leave the forger and die at the router.
        assert pub.wait_for_subscribers(10.0)
        for _ in range(20):
            pub.put(_forged(name, rng))
    _fence(bus)
    assert {n: receiver.count[n] for n in denied} == dict.fromkeys(denied, 0)
    # The rightful publishers' messages on the same keys arrive, all of them.
    owners = {"clock": "sim", "cmd_vel": "controller", "goal_status": "planner", "costmap": "mapper", "map": "mapper"}
    for name, owner in owners.items():
        if name not in denied:
            continue
        sender = client(owner)
        pub = sender.publisher(name)
        assert pub.wait_for_subscribers(10.0)
        for _ in range(5):
            pub.put(_forged(name, rng))
        _fence(sender)
        assert receiver.count[name] == 5, name


def test_the_operator_may_drive_and_send_goals(client: Callable[[str], Bus]) -> None:
    receiver = Receiver(client(RECEIVER))
    bus = client(OPERATOR)
    rng = np.random.default_rng(3)
    for name in ("cmd_vel", "goal", "cancel"):
        pub = bus.publisher(name)
        assert pub.wait_for_subscribers(10.0)
        pub.put(_forged(name, rng))
    _fence(bus)
    assert [receiver.count[n] for n in ("cmd_vel", "goal", "cancel")] == [1, 1, 1]


def test_forged_tokens_and_endpoints_are_refused(client: Callable[[str], Bus]) -> None:
    observer = client("viz")
    intruder = client(INTRUDER)
    intruder.declare_alive("planner")  # would make the launcher believe a dead planner is alive
    intruder.declare_lockstep("mapper")  # would make the sim wait for a participant that never steps
    real = client("controller")
    real.declare_alive("controller")
    real.declare_lockstep("controller")
    # The real token takes a moment to reach the observer through the router: ask until it is there; the forged
    # ones must never be (each answer is checked, not only the last).
    answers: list[list[str]] = []
    assert wait_until(lambda: answers.append(observer.alive_services(0.5)) or "controller" in answers[-1], 20.0)
    assert all(a in ([], ["controller"]) for a in answers), answers

    def lockstep_tokens() -> list[str]:
        replies = observer.session.liveliness().get(lockstep_key("robot0", "*"), timeout=0.5)
        return [str(r.ok.key_expr) for r in replies if r.ok is not None]

    seen: list[list[str]] = []
    assert wait_until(lambda: seen.append(lockstep_tokens()) or bool(seen[-1]), 20.0)
    assert all(a in ([], [lockstep_key("robot0", "controller")]) for a in seen), seen
    # Only the mapper may serve save_map, and only the operator may call it (it writes files).
    string = msg_class("std_msgs/msg/String")
    intruder.serve("save_map", lambda _req: string(data='{"yaml": "/etc/passwd"}'))
    with pytest.raises(NoReply):
        client(OPERATOR).call("save_map", timeout_s=1.0)
    mapper = client("mapper")
    mapper.serve("save_map", lambda _req: string(data='{"yaml": "maps/map.yaml"}'))
    assert client(OPERATOR).call("save_map", timeout_s=5.0).data == '{"yaml": "maps/map.yaml"}'
    with pytest.raises(NoReply):  # a fresh session: the first one would answer itself
        client(INTRUDER).call("save_map", timeout_s=1.0)


@pytest.mark.e2e
def test_fuzz_valid_but_forged_messages_from_unauthorised_identities_never_arrive(
    client: Callable[[str], Bus],
) -> None:
    rng = np.random.default_rng(2024)
    receiver = Receiver(client(RECEIVER))
    table = grants("robot0", SERVICES)
    sent = 0
    for forger in (INTRUDER, "viz"):
        bus = client(forger)
        for name in PUBLISH_RIGHTS:
            service = _target(name, "sim")
            if allowed(table, forger, "put", TOPICS[name].key("robot0", service)):
                continue
            pub = bus.publisher(name, service=service)
            assert pub.wait_for_subscribers(10.0)
            for _ in range(FORGED_PER_KEY):
                pub.put_bytes(encode(_forged(name, rng)))
                sent += 1
        _fence(bus)
    assert sent >= 10_000
    assert sum(receiver.count.values()) == 0, {k: v for k, v in receiver.count.items() if v}
