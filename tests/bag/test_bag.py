"""MCAP bags over real Zenoh: record (ROS 2 profile, read back by mcap_ros2), replay with the recorded timing,
namespace moves and key filters, ``mjnav bag info`` and the CLI's errors."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

from mjnav.bag import BagWriter, bag_info, key_expressions, play, record
from mjnav.bus import Bus, wait_until
from mjnav.geometry import Pose2D
from mjnav.msgs import encode, from_dict, ros, topic
from tests.conftest import REPO

Peer = Callable[..., Bus]


def _mjnav(*args: str, timeout: float = 60.0) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    return subprocess.run(
        [sys.executable, "-m", "mjnav", *args], cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout
    )


def read_ros2_messages(path: Path) -> Any:
    """``mcap_ros2.reader.read_ros2_messages`` (its module warns it is deprecated in favour of the same decoder)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from mcap_ros2.reader import read_ros2_messages as read

    return read(path)


def _odom(t: float) -> Any:
    return ros.odometry(t, Pose2D(t, 0.0, 0.0), 1.0, 0.0)


def _status() -> Any:
    return from_dict("mjnav_msgs/msg/ServiceStatus", {"service": "sim", "robot_namespace": "robot0", "state": 2})


def _scan(t: float) -> Any:
    return ros.laser_scan(
        t, "laser", angle_min_rad=-1.0, angle_increment_rad=0.5, scan_time_s=0.1, range_min_m=0.1, range_max_m=5.0,
        ranges_m=[1.0, 2.0, float("inf"), 3.0, 0.5],
    )  # fmt: skip


def test_record_writes_a_ros2_mcap_that_mcap_ros2_decodes(peer: Peer, tmp_path: Path) -> None:
    recorder, me = peer(), peer()
    out = tmp_path / "run.mcap"
    pubs = {name: me.publisher(name) for name in ("odom", "scan", "goal")}
    status = me.publisher("status", service="sim")
    result: list[Any] = []
    good = 10 + 3 + 2 + 1
    thread = threading.Thread(
        target=lambda: result.append(record(recorder, out, key_expressions(None, "robot0"), max_messages=good))
    )
    thread.start()
    for pub in (*pubs.values(), status):
        assert pub.wait_for_subscribers(10.0), f"the recorder never subscribed to {pub.key}"
    # What a recorder must not write: bytes that are not CDR of the type, another encoding, a key outside the table.
    me.session.put(me.key("odom"), b"\x00\x01\x00\x00garbage")
    me.session.put(me.key("scan"), b"{}", encoding="application/json")
    me.session.put(f"{me.namespace}/not_a_topic", encode(_odom(0.0)))
    for i in range(3):
        pubs["scan"].put(_scan(0.1 * i))
    pubs["goal"].put(ros.pose_stamped(0.5, "map", Pose2D(1.0, 2.0, 0.0)))
    pubs["goal"].put(ros.pose_stamped(0.6, "map", Pose2D(3.0, 4.0, 0.0)))
    status.put(_status())
    for i in range(10):
        pubs["odom"].put(_odom(0.1 * (i + 1)))
    thread.join(30.0)
    assert not thread.is_alive() and result, "recording did not end after the expected messages"
    stats = result[0]
    assert stats.total == good
    assert stats.skipped == {"undecodable": 1, "encoding": 1, "unknown key": 1}

    with open(out, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
        assert {c.message_encoding for c in summary.channels.values()} == {"cdr"}
        keys = {c.topic: c.metadata["zenoh_key"] for c in summary.channels.values()}
    assert keys["/robot0/odom"] == "robot0/odom" and keys["/robot0/status/sim"] == "robot0/status/sim"

    decoded: dict[str, list[Any]] = {}
    for m in read_ros2_messages(out):
        decoded.setdefault(m.channel.topic, []).append(m.ros_msg)
    assert {t: len(v) for t, v in decoded.items()} == {
        "/robot0/odom": 10,
        "/robot0/scan": 3,
        "/robot0/goal": 2,
        "/robot0/status/sim": 1,
    }
    odom_x = [m.pose.pose.position.x for m in decoded["/robot0/odom"]]
    assert odom_x == pytest.approx([0.1 * (i + 1) for i in range(10)])
    assert decoded["/robot0/goal"][1].pose.position.y == 4.0
    assert decoded["/robot0/status/sim"][0].service == "sim"
    assert list(decoded["/robot0/scan"][0].ranges[:2]) == [1.0, 2.0]


def _synthetic_bag(path: Path, span_s: float = 1.0, n: int = 11) -> int:
    """A bag with ``n`` odom messages spread evenly over ``span_s`` and one goal halfway; returns its message count."""
    t0 = 1_700_000_000_000_000_000
    with BagWriter(path) as writer:
        for i in range(n):
            t = t0 + round(i * span_s / (n - 1) * 1e9)
            assert writer.add(topic("odom").key(), encode(_odom(0.1 * i)), log_time_ns=t)
            if i == n // 2:
                goal = ros.pose_stamped(0.5, "map", Pose2D(1.0, 2.0, 0.0))
                assert writer.add(topic("goal").key(), encode(goal), log_time_ns=t + 1)
    return n + 1


@pytest.mark.e2e
def test_play_republishes_at_the_recorded_times(router_endpoint: str, peer: Peer, tmp_path: Path) -> None:
    bag = tmp_path / "synthetic.mcap"
    total = _synthetic_bag(bag, span_s=1.0)
    me = peer()
    received: list[float] = []
    odom = me.subscribe("odom", callback=lambda m: received.append(m.pose.pose.position.x))
    goals = me.subscribe("goal")
    proc = _mjnav("bag", "play", str(bag), "--rtf", "2", "--connect", router_endpoint, "--wait", "10")
    assert proc.returncode == 0, proc.stderr
    assert f"published {total} messages on 2 keys" in proc.stderr
    assert wait_until(lambda: len(received) == total - 1, 10.0), f"received {len(received)} odom messages"
    assert received == pytest.approx([0.1 * i for i in range(total - 1)])  # in order
    assert odom.count == total - 1
    got = goals.wait(5.0, lambda g: g.pose.position.y == 2.0) or goals.latest()
    assert got is not None and got.pose.position.x == 1.0


@pytest.mark.e2e
def test_play_moves_the_namespace_and_filters_keys(peer: Peer, tmp_path: Path) -> None:
    bag = tmp_path / "synthetic.mcap"
    _synthetic_bag(bag, span_s=0.2)
    player, robot1 = peer(), peer("robot1")
    goals = robot1.subscribe("goal")
    xs: list[float] = []
    # One subscription per key: the player waits for a matching subscriber, which must be the one counted.
    odom = robot1.subscribe("odom", callback=lambda m: xs.append(m.pose.pose.position.x))
    stats = play(bag, player, rtf=1.0, namespace="robot1", key_expressions=["robot0/odom"], wait_subscribers_s=10.0)
    assert stats.messages == {"robot1/odom": 11}
    assert stats.skipped_channels == {"/robot0/goal": "filtered out"}
    assert stats.bag_span_s == pytest.approx(0.2)
    assert wait_until(lambda: len(xs) == 11, 10.0)
    assert odom.latest().pose.pose.position.x == pytest.approx(1.0)
    assert goals.latest() is None


@pytest.mark.e2e
def test_bag_info_and_cli_errors(tmp_path: Path) -> None:
    bag = tmp_path / "synthetic.mcap"
    total = _synthetic_bag(bag)
    info = bag_info(bag)
    assert info.complete and info.messages == total and info.duration_s == pytest.approx(1.0, abs=1e-6)
    rows = {c.key: c for c in info.channels}
    assert rows["robot0/odom"].messages == 11 and rows["robot0/odom"].rate_hz == pytest.approx(10.0)
    assert rows["robot0/goal"].msgtype == "geometry_msgs/msg/PoseStamped"

    text = _mjnav("bag", "info", str(bag))
    assert text.returncode == 0 and "/robot0/odom" in text.stdout and "nav_msgs/msg/Odometry" in text.stdout
    as_json = _mjnav("bag", "info", "--json", str(bag))
    assert json.loads(as_json.stdout)[0]["messages"] == total

    not_mcap = tmp_path / "notes.mcap"
    not_mcap.write_text("not a bag")
    bad = _mjnav("bag", "info", str(not_mcap))
    assert bad.returncode == 1 and "not a readable MCAP file" in bad.stderr
    exists = _mjnav("bag", "record", "--duration", "1", str(bag))
    assert exists.returncode == 2 and "exists; use --force" in exists.stderr
    unknown = _mjnav("bag", "record", "--keys", "odom", "lidar", str(tmp_path / "new.mcap"))
    assert unknown.returncode == 2 and "unknown topic 'lidar'" in unknown.stderr
    assert not (tmp_path / "new.mcap").exists()
