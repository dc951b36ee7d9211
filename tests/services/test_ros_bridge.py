"""The ros_bridge service against an independent rmw_zenoh client (``zenoh-ros2-sdk`` from PyPI), both ways.

The client builds its keys, liveliness tokens, attachments and RIHS01 type hashes itself, from the ROS 2 ``.msg``
definitions in ``tests/services/ros_msgs`` (the canonical field lists of common_interfaces and rcl_interfaces):
a sample only reaches it when the bridge's key — type hash included — is exactly what rmw_zenoh would use.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mjnav.bus import Bus, BusConfig, wait_until
from mjnav.msgs import from_dict, ros
from mjnav.msgs.rmw_zenoh import GID_BYTES, parse_attachment
from mjnav.runtime.config import ConfigError
from mjnav.runtime.stack import load_stack
from mjnav.services.ros_bridge import RosBridgeConfig, RosBridgeService
from tests.services.test_navigation import up_process

sdk = pytest.importorskip("zenoh_ros2_sdk", reason="the rmw_zenoh peer (pip install zenoh-ros2-sdk) is not installed")

MSG_DIR = Path(__file__).parent / "ros_msgs"
DOMAIN = 7


@pytest.fixture
def bridge(peer: Callable[..., Bus]) -> Iterator[RosBridgeService]:
    service = RosBridgeService(RosBridgeConfig(domain_id=DOMAIN), peer(), logging.getLogger("test.ros_bridge"))
    service.configure()
    service.activate()
    yield service
    service.deactivate()


@contextmanager
def sdk_session(endpoint: str, domain_id: int = DOMAIN) -> Iterator[dict[str, Any]]:
    """Where the rmw_zenoh client connects (its keyword arguments); its process-wide session is closed and
    forgotten afterwards."""
    from zenoh_ros2_sdk import message_registry
    from zenoh_ros2_sdk.session import ZenohSession

    message_registry._registry = None
    sdk.get_registry(str(MSG_DIR))
    host, port = endpoint.removeprefix("tcp/").rsplit(":", 1)
    try:
        yield {"router_ip": host, "router_port": int(port), "domain_id": domain_id}
    finally:
        if ZenohSession._instance is not None:
            ZenohSession._instance.close()
            ZenohSession._instance = None
        message_registry._registry = None


@pytest.fixture
def ros_client(router_endpoint: str) -> Iterator[dict[str, Any]]:
    with sdk_session(router_endpoint) as kwargs:
        yield kwargs


@pytest.mark.e2e
def test_a_ros2_subscriber_receives_the_stacks_scan_and_lists_the_topic(
    bridge: RosBridgeService, ros_client: dict[str, Any], peer: Callable[..., Bus]
) -> None:
    got: list[Any] = []
    sub = sdk.ROS2Subscriber("/robot0/scan", "sensor_msgs/msg/LaserScan", got.append, **ros_client)
    try:
        sim = peer()
        pub = sim.publisher("scan")
        ranges = np.linspace(0.5, 4.0, 90).astype(np.float32)
        scan = from_dict(
            "sensor_msgs/msg/LaserScan",
            {
                "header": {"stamp": {"sec": 12, "nanosec": 500}, "frame_id": "laser"},
                "angle_min": -1.5,
                "angle_max": 1.5,
                "angle_increment": 3.0 / 89,
                "range_min": 0.1,
                "range_max": 8.0,
                "ranges": ranges.tolist(),
            },
        )

        def delivered() -> bool:
            pub.put(scan)  # re-sent until the routes of the bridge and the client are up
            return bool(got)

        assert wait_until(delivered, 10.0, poll_s=0.05)
        msg = got[0]
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (12, 500, "laser")
        np.testing.assert_array_equal(np.asarray(msg.ranges, dtype=np.float32), ranges)
        assert msg.angle_min == pytest.approx(-1.5)
        topics: dict[str, list[str]] = {}

        def listed() -> bool:  # a fresh client learns the graph from the router's tokens: ask until it has them
            topics.update(sdk.get_topic_names_and_types(timeout=1.0, **ros_client))
            return {"/robot0/scan", "/robot0/cmd_vel"} <= topics.keys()

        assert wait_until(listed, 10.0, poll_s=0.1)
        assert topics["/robot0/scan"] == ["sensor_msgs/msg/LaserScan"]
        assert topics["/robot0/cmd_vel"] == ["geometry_msgs/msg/Twist"]  # the bridge's inbound subscription
        assert "/robot0/odom" not in topics  # nothing published it: no publisher token
    finally:
        sub.close()


@pytest.mark.e2e
def test_the_bridge_puts_rmw_zenoh_attachments_on_what_it_relays(
    bridge: RosBridgeService, peer: Callable[..., Bus]
) -> None:
    watcher = peer()
    attachments: list[bytes] = []
    key = f"{DOMAIN}/robot0/clock/rosgraph_msgs::msg::dds_::Clock_/**"
    watcher.session.declare_subscriber(key, lambda s: attachments.append(s.attachment.to_bytes()))
    pub = peer().publisher("clock")

    def two() -> bool:
        pub.put(from_dict("rosgraph_msgs/msg/Clock", {"clock": {"sec": 1}}))
        return len(attachments) >= 2

    assert wait_until(two, 10.0, poll_s=0.05)
    (seq0, t0, gid0), (seq1, t1, gid1) = parse_attachment(attachments[0]), parse_attachment(attachments[1])
    assert seq1 == seq0 + 1 and t1 >= t0 > 1_600_000_000 * 10**9  # ns since the UNIX epoch
    assert gid0 == gid1 and len(gid0) == GID_BYTES


def test_a_ros2_node_drives_the_robot_and_sends_a_goal(
    bridge: RosBridgeService, ros_client: dict[str, Any], peer: Callable[..., Bus]
) -> None:
    stack = peer()
    cmd_vel = stack.subscribe("cmd_vel")
    goals = stack.subscribe("goal")
    twist_pub = sdk.ROS2Publisher("/robot0/cmd_vel", "geometry_msgs/msg/Twist", **ros_client)
    goal_pub = sdk.ROS2Publisher("/robot0/goal", "geometry_msgs/msg/PoseStamped", **ros_client)
    try:
        vector = sdk.get_message_class("geometry_msgs/msg/Vector3")

        def driven() -> bool:
            twist_pub.publish(linear=vector(x=0.3, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=-0.7))
            return cmd_vel.latest() is not None

        assert wait_until(driven, 10.0, poll_s=0.05)
        twist = cmd_vel.latest()
        assert (twist.linear.x, twist.angular.z) == (0.3, -0.7)
        time_cls = sdk.get_message_class("builtin_interfaces/msg/Time")
        header = sdk.get_message_class("std_msgs/msg/Header")(stamp=time_cls(sec=3, nanosec=0), frame_id="map")
        pose = sdk.get_message_class("geometry_msgs/msg/Pose")(
            position=sdk.get_message_class("geometry_msgs/msg/Point")(x=2.5, y=-1.0, z=0.0),
            orientation=sdk.get_message_class("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0),
        )

        def goal_sent() -> bool:
            goal_pub.publish(header=header, pose=pose)
            return bool(goals.wait(0.1))

        assert wait_until(goal_sent, 10.0, poll_s=0.0)
        goal = goals.drain()[0]
        assert (goal.header.frame_id, goal.pose.position.x, goal.pose.position.y) == ("map", 2.5, -1.0)
        assert ros.seconds(goal.header.stamp) == 3.0
        assert bridge.counts["in"] >= 2
    finally:
        twist_pub.close()
        goal_pub.close()


@pytest.mark.e2e
def test_nothing_loops_between_the_two_sides(bridge: RosBridgeService, peer: Callable[..., Bus]) -> None:
    """The stack's own cmd_vel goes out once per message and is never taken for a ROS 2 command coming in (the
    bridge's own rmw_zenoh samples are local to its session, which its inbound subscription does not accept)."""
    stack = peer()
    seen: list[Any] = []
    stack.subscribe("cmd_vel", callback=seen.append)
    rmw: list[str] = []
    stack.session.declare_subscriber(f"{DOMAIN}/robot0/cmd_vel/**", lambda s: rmw.append(str(s.key_expr)))
    pub = peer().publisher("cmd_vel")
    assert wait_until(lambda: bool(pub.put(ros.twist(0.1, 0.0))) or bool(rmw), 10.0, poll_s=0.05)
    before_rmw, before_seen = len(rmw), len(seen)
    for i in range(5):
        pub.put(ros.twist(0.2 + i, 0.0))
    assert wait_until(lambda: len(rmw) >= before_rmw + 5 and len(seen) >= before_seen + 5, 5.0)
    assert bridge.counts["in"] == 0
    assert len(set(rmw)) == 1  # one rmw_zenoh key: the Twist's, with its type hash


def test_the_bridge_is_an_optional_service_of_the_stack() -> None:
    stack = load_stack()
    assert "ros_bridge" not in stack.names()
    spec = stack.get("ros_bridge")  # what `mjnav run ros_bridge` (and so `mjnav up --ros rmw_zenoh`) starts
    config = spec.load_config({"domain_id": 3})
    assert isinstance(config, RosBridgeConfig) and config.resolved_domain() == 3
    assert stack.with_services(["ros_bridge"]).names() == [*stack.names(), "ros_bridge"]
    with pytest.raises(ConfigError, match="optional: ros_bridge"):
        stack.with_services(["nope"])


@pytest.mark.parametrize(
    ("fields", "match"),
    [
        ({"domain_id": 233}, "domain"),
        ({"inbound": ("scan",)}, "operator"),
        ({"outbound": ("status",)}, "per service"),
        ({"outbound": ("nope",)}, "unknown topic"),
    ],
)
def test_bad_bridge_settings_are_refused(fields: dict[str, Any], match: str) -> None:
    with pytest.raises(ValueError, match=match):
        RosBridgeConfig(**fields)


@pytest.mark.e2e
def test_mjnav_up_ros_rmw_zenoh_a_ros2_node_drives_the_simulated_robot() -> None:
    """The whole path: `mjnav up --ros rmw_zenoh` with the sim; a ROS 2 node (the independent client) reads the
    clock and odometry and publishes cmd_vel on domain 0, and the simulated robot moves."""
    with up_process("--only", "sim", "--ros", "rmw_zenoh", "--set", "ros_bridge.domain_id=0") as (port, _, lines):
        bus = Bus.open(BusConfig(connect=(f"tcp/127.0.0.1:{port}",)))
        try:
            assert wait_until(lambda: {"sim", "ros_bridge"} <= set(bus.alive_services(0.5)), 120.0), "".join(lines)
            with sdk_session(f"tcp/127.0.0.1:{port}", domain_id=0) as kwargs:
                clocks: list[Any] = []
                sdk.ROS2Subscriber("/robot0/clock", "rosgraph_msgs/msg/Clock", clocks.append, **kwargs)
                odom: list[Any] = []
                sdk.ROS2Subscriber("/robot0/odom", "nav_msgs/msg/Odometry", odom.append, **kwargs)
                twist = sdk.ROS2Publisher("/robot0/cmd_vel", "geometry_msgs/msg/Twist", **kwargs)
                vector = sdk.get_message_class("geometry_msgs/msg/Vector3")

                def moving() -> bool:
                    twist.publish(linear=vector(x=0.4, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=0.0))
                    return bool(odom) and odom[-1].twist.twist.linear.x > 0.2

                assert wait_until(moving, 60.0, poll_s=0.05), "".join(lines)[-3000:]
                assert clocks and clocks[-1].clock.sec + clocks[-1].clock.nanosec * 1e-9 > 0.0
        finally:
            bus.close()
