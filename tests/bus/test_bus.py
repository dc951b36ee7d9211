"""Typed pub/sub, rejection of bad payloads, request/reply and liveliness over real Zenoh on loopback."""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable

import pytest
import zenoh

from mjnav.bus import Bus, NoReply, RemoteError, cdr_encoding, wait_until
from mjnav.geometry import Pose2D
from mjnav.msgs import encode, from_dict, msg_class, ros
from mjnav.msgs.topics import endpoint

Peer = Callable[..., Bus]


def test_snapshot_topic_delivers_decoded_messages_and_keeps_the_newest(peer: Peer) -> None:
    a, b = peer(), peer()
    sub = b.subscribe("cmd_vel")
    pub = a.publisher("cmd_vel")
    assert pub.wait_for_subscribers(5.0)
    for i in range(20):
        pub.put(ros.twist(0.1 * i, -0.5))
    last = sub.wait(5.0, lambda m: math.isclose(m.linear.x, 1.9))
    assert last is not None and last.angular.z == -0.5
    assert sub.take() is last and sub.take() is None  # take() hands out each newest message once
    assert b.stats.rejected == 0 and a.stats.published == 20


def test_a_latched_message_that_arrived_before_wait_is_returned_by_it(peer: Peer) -> None:
    """A late joiner's history can arrive between subscribe() and wait(): wait() must still hand it out (it failed
    4 times in 11 under load, the sim test's tf_static), and a second wait() waits for a newer message."""
    a, b = peer(), peer()
    pub = a.publisher("tf_static")
    pub.put(ros.tf_message(ros.transform_stamped_3d(0.0, "base_link", "laser", (0.0, 0.0, 0.2), (0.0, 0.0, 0.0, 1.0))))
    arrived = threading.Event()
    sub = b.subscribe("tf_static", callback=lambda _msg: arrived.set())
    assert arrived.wait(10.0), "the latched message never reached the late joiner"
    first = sub.wait(10.0)  # it arrived before the call
    assert first is not None and first.transforms[0].child_frame_id == "laser"
    assert sub.wait(0.2) is None  # already handed out: only a newer one counts now
    assert sub.latest() is first


@pytest.mark.e2e
def test_event_topic_keeps_every_message_in_order(peer: Peer) -> None:
    a, b = peer(), peer()
    sub = b.subscribe("goal")
    pub = a.publisher("goal")
    assert pub.wait_for_subscribers(5.0)
    for i in range(300):
        pub.put(ros.pose_stamped(float(i), "map", Pose2D(float(i), 0.0, 0.0)))
    assert sub.wait(10.0, lambda m: m.pose.position.x == 299.0) is not None
    xs = [m.pose.position.x for m in sub.drain()]
    assert xs == [float(i) for i in range(300)]
    assert sub.drain() == []


@pytest.mark.e2e
def test_bad_payloads_are_counted_and_logged_never_raised(peer: Peer, caplog: pytest.LogCaptureFixture) -> None:
    a, b = peer(), peer()
    sub = b.subscribe("cmd_vel")
    pub = a.publisher("cmd_vel")
    assert pub.wait_for_subscribers(5.0)
    key = b.key("cmd_vel")
    nan_twist = encode(from_dict("geometry_msgs/msg/Twist", {"angular": {"z": math.nan}}))
    scan_bytes = encode(from_dict("sensor_msgs/msg/LaserScan", {"range_max": 5.0, "ranges": [1.0] * 10}))
    with caplog.at_level(logging.WARNING, logger="mjnav.bus"):
        a.session.put(key, b"not cdr at all")
        a.session.put(key, nan_twist[:20])
        a.session.put(key, nan_twist, encoding=cdr_encoding("geometry_msgs/msg/Twist"))
        a.session.put(key, scan_bytes, encoding=cdr_encoding("sensor_msgs/msg/LaserScan"))
        a.session.put(key, b"{}", encoding=zenoh.Encoding.APPLICATION_JSON)
        assert wait_until(lambda: b.stats.rejected == 5, 5.0), b.stats
        pub.put(ros.twist(0.3, 0.0))  # the subscription still works afterwards
        assert sub.wait(5.0, lambda m: m.linear.x == 0.3) is not None
    assert b.stats.rejected_by_key == {key: 5}
    text = caplog.text
    assert key in text and "is nan" in text and "wrong type sensor_msgs/msg/LaserScan" in text
    assert "wrong encoding" in text and "encapsulation" in text


@pytest.mark.e2e
def test_wildcard_subscription_keeps_the_newest_per_key(peer: Peer) -> None:
    a, b = peer(), peer()
    sub = b.subscribe("status", service="*")
    status = msg_class("mjnav_msgs/msg/ServiceStatus")
    pubs = {name: a.publisher("status", service=name) for name in ("sim", "planner")}
    for pub in pubs.values():
        assert pub.wait_for_subscribers(5.0)
    for name, pub in pubs.items():
        msg = from_dict("mjnav_msgs/msg/ServiceStatus", {"service": name, "steps": 7})
        assert isinstance(msg, status)
        pub.put(msg)
    assert wait_until(lambda: len(sub.latest_by_key()) == 2, 5.0)
    by_key = sub.latest_by_key()
    assert by_key[b.key("status", "sim")].service == "sim"
    assert by_key[b.key("status", "planner")].service == "planner"


@pytest.mark.e2e
def test_request_reply(peer: Peer) -> None:
    server, client = peer(), peer()
    string = msg_class("std_msgs/msg/String")

    def handler(req: object) -> object:
        text = req.data  # type: ignore[attr-defined]
        if text == "boom":
            raise RuntimeError("exploded on purpose")
        return string(data=text.upper())

    server.serve("config", handler, service="echo")
    server.declare_alive("echo")
    assert wait_until(lambda: client.alive_services() == ["echo"], 5.0)
    assert client.call("config", string(data="hello"), service="echo").data == "HELLO"
    with pytest.raises(RemoteError, match="exploded on purpose"):
        client.call("config", string(data="boom"), service="echo")
    with pytest.raises(NoReply):
        client.call("config", string(data="x"), service="nobody", timeout_s=0.5)


def test_a_reply_that_does_not_decode_is_a_remote_error_sync_and_async(peer: Peer) -> None:
    server, client = peer(), peer()
    key = endpoint("config").key(server.namespace, "liar")
    liar = server.session.declare_queryable(key, lambda query: query.reply(key, b"\x07garbage"))
    server.declare_alive("liar")  # declared after the queryable: once the client sees it, it can reach the queryable
    assert wait_until(lambda: client.alive_services() == ["liar"], 5.0)
    with pytest.raises(RemoteError, match="undecodable reply"):
        client.call("config", service="liar")
    errors: list[Exception] = []
    done = threading.Event()

    def on_error(exc: Exception) -> None:
        errors.append(exc)
        done.set()

    client.call_async("config", None, lambda _reply: done.set(), on_error, service="liar")
    assert done.wait(5.0)
    assert len(errors) == 1 and isinstance(errors[0], RemoteError) and "undecodable" in str(errors[0])
    liar.undeclare()


def test_liveliness_appears_and_disappears(peer: Peer, router_endpoint: str) -> None:
    watcher = peer()
    events: list[tuple[str, bool]] = []
    changed = threading.Event()

    def on_change(service: str, alive: bool) -> None:
        events.append((service, alive))
        changed.set()

    watcher.watch_alive(on_change)
    other = peer()
    other.declare_alive("mapper")
    assert wait_until(lambda: ("mapper", True) in events, 5.0)
    other.close()
    assert wait_until(lambda: ("mapper", False) in events, 5.0)
    assert changed.is_set()


def test_namespaces_do_not_mix(peer: Peer) -> None:
    a, b, c, d = peer("robot1"), peer("robot1"), peer("robot2"), peer("robot2")
    sub1, sub2 = b.subscribe("goal"), c.subscribe("goal")
    pub1, pub2 = a.publisher("goal"), d.publisher("goal")
    assert pub1.wait_for_subscribers(5.0) and pub2.wait_for_subscribers(5.0)
    pub1.put(ros.pose_stamped(0.0, "map", Pose2D(1.0, 0.0, 0.0)))
    pub2.put(ros.pose_stamped(0.0, "map", Pose2D(2.0, 0.0, 0.0)))  # a marker sent after robot1's goal
    arrived = lambda m: m is not None  # noqa: E731 - also true for a message that came before the call
    assert sub1.wait(5.0, arrived) is not None and sub2.wait(5.0, arrived) is not None
    # Events are reliable and ordered per publisher: had robot1's goal leaked into robot2, it would be queued too.
    assert [m.pose.position.x for m in sub2.drain()] == [2.0]
    assert [m.pose.position.x for m in sub1.drain()] == [1.0]


@pytest.mark.e2e
def test_a_network_thread_keeps_its_python_state_between_messages(peer: Peer) -> None:
    """Callbacks run in Zenoh's own threads; entering Python there made and deleted a thread state per message (a
    16 KB frame stack mapped and unmapped each time). Kept, a thread's state (and so its thread-local data)
    outlives one callback."""
    a, b = peer(), peer()
    local = threading.local()
    seen: list[int] = []

    def on_goal(_msg: object) -> None:
        seen.append(getattr(local, "calls", 0))  # callbacks this thread made before, as far as its state knows
        local.calls = seen[-1] + 1

    b.subscribe("goal", callback=on_goal)
    pub = a.publisher("goal")
    assert pub.wait_for_subscribers(5.0)
    for i in range(100):
        pub.put(ros.pose_stamped(float(i), "map", Pose2D(float(i), 0.0, 0.0)))
    assert wait_until(lambda: len(seen) == 100, 5.0)
    # Zenoh runs the callbacks on its few network threads (two by default): one of them made at least 10 calls.
    assert max(seen) >= 9, seen
