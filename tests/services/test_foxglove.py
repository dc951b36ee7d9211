"""The foxglove service seen from a WebSocket client speaking the Foxglove protocol (``websockets``): channels with
ROS 2 schemas, CDR messages that decode to what was published, and a live lockstep stack's scan, map and tf."""

from __future__ import annotations

import json
import logging
import socket
import struct
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from mjnav.bus import Bus, wait_until
from mjnav.msgs import decode, message_definition, ros
from mjnav.msgs.topics import TOPICS
from mjnav.runtime.stack import load_stack, services_dir
from mjnav.services.foxglove import FoxgloveConfig, FoxgloveService, streamed_topics
from mjnav.sim.worlds import world_info
from tests.conftest import free_port
from tests.services.test_navigation import up_process

pytest.importorskip("foxglove", reason="the foxglove extra (pip install foxglove-sdk) is not installed")
ws_client = pytest.importorskip("websockets.sync.client")

#: The WebSocket subprotocol of foxglove-sdk's server (what the Foxglove app asks for).
SUBPROTOCOL = "foxglove.sdk.v1"
#: Binary server opcode of a message on a subscription: opcode u8, subscription id u32, receive time u64, payload.
MESSAGE_DATA = 0x01


class FoxgloveClient:
    """A minimal Foxglove WebSocket client: reads the advertised channels, subscribes by topic, decodes CDR."""

    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.channels: dict[str, dict[str, Any]] = {}
        self._topic_of: dict[int, str] = {}

    def read_advertisements(self, topics: set[str], timeout_s: float = 10.0) -> None:
        """Read control messages until every topic of ``topics`` is advertised."""
        while not topics <= self.channels.keys():
            frame = self.ws.recv(timeout=timeout_s)
            if isinstance(frame, str):
                op = json.loads(frame)
                if op["op"] == "advertise":
                    self.channels.update({c["topic"]: c for c in op["channels"]})

    def subscribe(self, topics: list[str]) -> None:
        subs = []
        for i, name in enumerate(topics, start=1):
            subs.append({"id": i, "channelId": self.channels[name]["id"]})
            self._topic_of[i] = name
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def messages(self, want: Callable[[dict[str, list[Any]]], bool], timeout_s: float) -> dict[str, list[Any]]:
        """Decoded messages per topic, read until ``want`` holds for what arrived (``want`` is asked again at least
        every 0.2 s, so it may re-send what it waits for)."""
        got: dict[str, list[Any]] = {}
        deadline = time.monotonic() + timeout_s
        while not want(got):
            if time.monotonic() > deadline:
                raise TimeoutError(f"got only { ({t: len(m) for t, m in got.items()}) }")
            try:
                frame = self.ws.recv(timeout=0.2)
            except TimeoutError:
                continue
            if isinstance(frame, bytes) and frame[0] == MESSAGE_DATA:
                sub_id, _ = struct.unpack_from("<IQ", frame, 1)
                topic = self._topic_of[sub_id]
                got.setdefault(topic, []).append(decode(frame[13:], self.channels[topic]["schemaName"]))
        return got


@contextmanager
def foxglove_client(port: int) -> Iterator[FoxgloveClient]:
    with ws_client.connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], open_timeout=10, max_size=None) as ws:
        yield FoxgloveClient(ws)


def _listening(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


@pytest.fixture
def foxglove_service(peer: Callable[..., Bus]) -> Iterator[FoxgloveService]:
    service = FoxgloveService(FoxgloveConfig(port=0), peer(), logging.getLogger("test.foxglove"))
    service.configure()
    service.activate()
    yield service
    service.deactivate()


@pytest.mark.e2e
def test_channels_carry_ros2_schemas_and_messages_decode_to_what_was_published(
    foxglove_service: FoxgloveService, peer: Callable[..., Bus]
) -> None:
    with foxglove_client(foxglove_service.port) as client:
        client.read_advertisements({"/robot0/scan", "/robot0/tf", "/robot0/map"})
        scan = client.channels["/robot0/scan"]
        assert (scan["encoding"], scan["schemaEncoding"], scan["schemaName"]) == (
            "cdr",
            "ros2msg",
            "sensor_msgs/msg/LaserScan",
        )
        assert scan["schema"] == message_definition("sensor_msgs/msg/LaserScan")
        assert not any(t.startswith("/robot0/status") for t in client.channels)  # per-service topics are not streamed
        client.subscribe(["/robot0/cmd_vel"])
        sender = peer()
        pub = sender.publisher("cmd_vel")

        def send(got: dict[str, list[Any]]) -> bool:
            if got:
                return True
            pub.put(ros.twist(0.25, -0.5))  # re-sent until the server has the client's subscription
            return False

        twist = client.messages(send, timeout_s=10.0)["/robot0/cmd_vel"][0]
        assert (twist.linear.x, twist.angular.z) == (0.25, -0.5)
        # Now subscribed: a payload that is not CDR is dropped, the next good one still arrives.
        sender.session.put("robot0/cmd_vel", b"not cdr", encoding="text/plain")
        pub.put(ros.twist(0.5, 0.0))
        later = client.messages(lambda got: bool(got), timeout_s=10.0)["/robot0/cmd_vel"]
        assert [m.linear.x for m in later] == [0.5]
        assert wait_until(lambda: foxglove_service.relays["cmd_vel"].dropped == 1, 5.0)


@pytest.mark.e2e
def test_every_topic_but_the_per_service_ones_is_streamed(foxglove_service: FoxgloveService) -> None:
    assert set(foxglove_service.relays) == {name for name, row in TOPICS.items() if not row.per_service}


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="per service"):
        FoxgloveConfig(topics=("status",))
    with pytest.raises(ValueError, match="port"):
        FoxgloveConfig(port=70000)


def test_the_layout_shows_topics_the_service_streams() -> None:
    layout = json.loads((services_dir() / "foxglove_layout.json").read_text(encoding="utf-8"))
    streamed = {f"/robot0/{row.name}" for row in streamed_topics(FoxgloveConfig())}
    panels = layout["configById"]
    used = set(panels["3D!mjnav"]["topics"])
    used |= {p["value"].split(".")[0] for p in panels["Plot!speed"]["paths"]}
    used |= {c["topicPath"] for k, c in panels.items() if k.startswith("RawMessages!")}
    assert used and used <= streamed
    assert load_stack().get("foxglove").config_file == Path(services_dir() / "foxglove.toml")


@pytest.mark.e2e
def test_a_live_lockstep_stack_streams_scan_map_and_tf() -> None:
    port = free_port()
    start = world_info("rooms").start  # where SLAM starts (else it waits for an initialpose)
    args = ["--only", "sim,slam", "--foxglove", "--world", "rooms"]
    args += ["--set", f"foxglove.port={port}"]
    args += ["--set", f"slam.initial_pose=[{start.x}, {start.y}, {start.theta}]"]
    with up_process(*args) as (_, proc, lines):
        up = wait_until(lambda: proc.poll() is not None or _listening(port), 120.0, poll_s=0.2)
        assert up and proc.poll() is None, "".join(lines)[-3000:]
        with foxglove_client(port) as client:
            topics = ["/robot0/scan", "/robot0/map", "/robot0/tf"]
            client.read_advertisements(set(topics))
            client.subscribe(topics)

            def enough(got: dict[str, list[Any]]) -> bool:
                tfs = [t for m in got.get("/robot0/tf", []) for t in m.transforms]
                frames = {(t.header.frame_id, t.child_frame_id) for t in tfs}
                scans, maps = got.get("/robot0/scan", []), got.get("/robot0/map", [])
                return len(scans) >= 3 and bool(maps) and {("odom", "base_link"), ("map", "odom")} <= frames

            got = client.messages(enough, timeout_s=120.0)
    stamps = [ros.seconds(s.header.stamp) for s in got["/robot0/scan"]]
    assert stamps == sorted(stamps) and stamps[-1] > stamps[0]  # sim time advances in lockstep
    grid = got["/robot0/map"][-1]
    assert grid.header.frame_id == "map" and grid.info.width * grid.info.height == len(grid.data)
    assert got["/robot0/scan"][0].header.frame_id == "laser"
