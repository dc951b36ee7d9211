"""`mjnav echo` and `mjnav topics` against live publishers on a loopback router."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from collections.abc import Callable

import pytest

from mjnav.bus import Bus
from mjnav.geometry import Pose2D
from mjnav.msgs import ros
from tests.conftest import REPO


def _mjnav(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "mjnav", *args], cwd=REPO, text=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )


@pytest.mark.e2e
def test_echo_prints_decoded_messages_as_json_lines(peer: Callable[..., Bus], router_endpoint: str) -> None:
    proc = _mjnav("echo", "robot0/goal", "--count", "2", "--connect", router_endpoint, "--timeout", "60")
    me = peer()
    pub = me.publisher("goal")
    assert pub.wait_for_subscribers(30.0), "echo never subscribed"
    pub.put(ros.pose_stamped(1.5, "map", Pose2D(1.0, 2.0, 0.0)))
    pub.put(ros.pose_stamped(2.5, "map", Pose2D(3.0, 4.0, 0.0)))
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    lines = [json.loads(line) for line in out.splitlines()]
    assert [m["pose"]["position"]["x"] for m in lines] == [1.0, 3.0]
    assert lines[1]["header"] == {"stamp": {"sec": 2, "nanosec": 500_000_000}, "frame_id": "map"}


@pytest.mark.e2e
def test_echo_times_out_with_exit_code_1(router_endpoint: str) -> None:
    proc = _mjnav("echo", "robot0/scan", "--connect", router_endpoint, "--timeout", "1")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 1 and "no message on robot0/scan" in err


def test_echo_rejects_unknown_keys() -> None:
    proc = _mjnav("echo", "robot0/nonsense", "--connect", "tcp/127.0.0.1:1")
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2 and "matches no topic" in err


@pytest.mark.e2e
def test_topics_lists_live_keys_with_type_and_rate(peer: Callable[..., Bus], router_endpoint: str) -> None:
    me = peer()
    me.declare_alive("tester")
    pub = me.publisher("cmd_vel")
    stop = threading.Event()

    def publish() -> None:
        while not stop.wait(0.02):  # a 50 Hz source for topics to measure
            pub.put(ros.twist(0.1, 0.0))

    thread = threading.Thread(target=publish)
    thread.start()
    try:
        proc = _mjnav("topics", "--duration", "1.5", "--json", "--connect", router_endpoint)
        out, err = proc.communicate(timeout=60)
    finally:
        stop.set()
        thread.join()
    assert proc.returncode == 0, err
    report = json.loads(out)
    rows = {r["key"]: r for r in report["topics"]}
    row = rows["robot0/cmd_vel"]
    assert row["type"] == "geometry_msgs/msg/Twist" and row["delivery"] == "snapshot"
    assert row["rate_hz"] > 5.0 and row["messages"] > 5
    assert report["services_alive"] == ["tester"]


@pytest.mark.e2e
def test_echo_stops_quietly_when_its_reader_goes_away(peer: Callable[..., Bus], router_endpoint: str) -> None:
    proc = _mjnav("echo", "robot0/cmd_vel", "--connect", router_endpoint)
    me = peer()
    pub = me.publisher("cmd_vel")
    assert pub.wait_for_subscribers(30.0)
    stop = threading.Event()

    def publish() -> None:
        while not stop.wait(0.02):
            pub.put(ros.twist(0.1, 0.0))

    thread = threading.Thread(target=publish)
    thread.start()
    try:
        assert proc.stdout is not None
        assert json.loads(proc.stdout.readline())["linear"]["x"] == 0.1
        proc.stdout.close()  # like `mjnav echo … | head -1`
        assert proc.wait(30) == 0
    finally:
        stop.set()
        thread.join()
    assert "BrokenPipe" not in proc.stderr.read()  # type: ignore[union-attr]
