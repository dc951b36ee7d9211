"""Acceptance of issue 7 against a live stack (`mjnav up --port P --headless`, world rooms):

* a plain Zenoh client (zenoh + rosbags only) decodes ``robot0/scan``, ``robot0/odom`` and ``robot0/map`` as
  standard ROS 2 messages with increasing stamps;
* the standalone example ``examples/zenoh_client.py`` runs without mjnav importable, prints scan and odom and sends
  a goal that arrives on ``robot0/goal``;
* ``mjnav bag record --connect tcp/127.0.0.1:P --duration 6 out.mcap`` yields an MCAP that
  ``mcap_ros2.reader.read_ros2_messages`` decodes, with scan, odom and map messages;
* ``mjnav up`` stops on SIGINT within 10 s with exit code 0.
"""

from __future__ import annotations

import itertools
import json
import math
import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path
from typing import Any

import pytest
import zenoh
from rosbags.typesys import Stores, get_typestore

from mjnav.bus import Bus, BusConfig
from mjnav.runtime.stack import load_stack
from tests.conftest import REPO, free_port

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

TYPES = {
    "scan": "sensor_msgs/msg/LaserScan",
    "odom": "nav_msgs/msg/Odometry",
    "map": "nav_msgs/msg/OccupancyGrid",
}
#: Runs the example with ``import mjnav`` made impossible.
NO_MJNAV = "import runpy, sys; sys.modules['mjnav'] = None; sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')"  # noqa: E501


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    env["PYTHONUNBUFFERED"] = "1"
    return env


class PlainClient:
    """Zenoh + rosbags, nothing from mjnav: records the header stamps of each decoded key."""

    def __init__(self, endpoint: str, names: list[str], namespace: str) -> None:
        self.store = get_typestore(Stores.ROS2_HUMBLE)
        self.stamps: dict[str, list[float]] = {n: [] for n in names}
        self.types: dict[str, str] = {}
        self._cond = threading.Condition()
        config = zenoh.Config()
        config.insert_json5("mode", json.dumps("client"))
        config.insert_json5("connect/endpoints", json.dumps([endpoint]))
        config.insert_json5("connect/timeout_ms", json.dumps(30_000))  # the stack's router may still be starting
        self.session = zenoh.open(config)
        for name in names:
            self.session.declare_subscriber(f"{namespace}/{name}", self._handler(name))

    def _handler(self, name: str) -> Any:
        def on_sample(sample: zenoh.Sample) -> None:
            msg = self.store.deserialize_cdr(sample.payload.to_bytes(), TYPES[name])
            stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            with self._cond:
                self.types[name] = msg.__msgtype__
                self.stamps[name].append(stamp)
                self._cond.notify_all()

        return on_sample

    def wait_counts(self, want: dict[str, int], timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while any(len(self.stamps[n]) < k for n, k in want.items()):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._cond.wait(remaining)
            return True


def _increasing(values: list[float]) -> bool:
    return all(b > a for a, b in itertools.pairwise(values))


def test_plain_clients_bags_and_sigint_during_mjnav_up(tmp_path: Path) -> None:
    stack = load_stack()
    names = stack.names()
    assert {"sim", "mapper"} <= set(names)
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    cmd = [sys.executable, "-m", "mjnav", "up", "--port", str(port), "--headless", "--world", "rooms"]
    if "viz" in names:
        cmd += ["--set", "viz.web_port=0", "--set", "viz.zmq_port=0"]
    up = subprocess.Popen(cmd, cwd=REPO, env=_env(), text=True, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    up_output: list[str] = []
    pump = threading.Thread(target=lambda: up_output.extend(up.stdout or []), daemon=True)
    pump.start()
    bag = tmp_path / "out.mcap"
    recorder: subprocess.Popen[str] | None = None
    client: PlainClient | None = None
    stopped_in: float | None = None
    code: int | None = None
    try:
        topics = ["scan", "odom", "map"]
        client = PlainClient(endpoint, topics, stack.namespace)
        want = {"scan": 5, "odom": 20, "map": 2}
        got = {k: len(v) for k, v in client.stamps.items()}
        assert client.wait_counts(want, 90.0), f"plain client got {got}"
        for name in topics:
            assert client.types[name] == TYPES[name]
            assert _increasing(client.stamps[name]), f"{name} stamps do not increase: {client.stamps[name][:10]}"

        # The stack is up (the mapper publishes): on a fresh clone its first start compiles the numba kernels, which
        # can outlast a 6 s bag started together with the launcher.
        recorder = subprocess.Popen(
            [sys.executable, "-m", "mjnav", "bag", "record", "--connect", endpoint, "--duration", "6", str(bag)],
            cwd=REPO,
            env=_env(),
            text=True,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
        )

        with Bus.open(BusConfig(connect=(endpoint,)), stack.namespace) as me:
            goals = me.subscribe("goal")
            example_args = ["--connect", endpoint, "--count", "3", "--json", "--goal", "3.8", "2.2", "1.5708"]
            example = subprocess.run(
                [sys.executable, "-c", NO_MJNAV, str(REPO / "examples" / "zenoh_client.py"), *example_args],
                cwd=tmp_path,
                env=_env(),
                capture_output=True,
                text=True,
                timeout=60,
            )
            assert example.returncode == 0, example.stderr
            records = [json.loads(line) for line in example.stdout.splitlines()]
            for name in ("scan", "odom"):
                stamps = [r["stamp"] for r in records if r["type"] == TYPES[name]]
                assert len(stamps) == 3 and _increasing(stamps), records
            goal = goals.wait(10.0) or goals.latest()
            assert goal is not None, "the example's goal never arrived"
            assert (goal.pose.position.x, goal.pose.position.y) == (3.8, 2.2) and goal.header.frame_id == "map"
            assert math.isclose(2 * math.atan2(goal.pose.orientation.z, goal.pose.orientation.w), 1.5708)

        out, _ = recorder.communicate(timeout=60)
        assert recorder.returncode == 0, out
    finally:
        if client is not None:
            client.session.close()
        if recorder is not None and recorder.poll() is None:
            recorder.kill()
        t0 = time.monotonic()
        up.send_signal(signal.SIGINT)
        try:
            code = up.wait(10.0)
            stopped_in = time.monotonic() - t0
        except subprocess.TimeoutExpired:
            up.kill()
            up.wait(10.0)
        pump.join(5.0)
    log = "".join(up_output)
    assert code == 0 and stopped_in is not None and stopped_in < 10.0, f"mjnav up: code {code}\n{log[-3000:]}"

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # mcap_ros2.reader warns about its own module
        from mcap_ros2.reader import read_ros2_messages

        counts: dict[str, int] = {}
        for m in read_ros2_messages(bag):
            counts[m.channel.topic] = counts.get(m.channel.topic, 0) + 1
            if m.channel.topic == f"/{stack.namespace}/scan":
                assert len(m.ros_msg.ranges) > 0
    for name in ["scan", "odom", "map"]:
        assert counts.get(f"/{stack.namespace}/{name}", 0) > 0, f"no {name} in the bag: {counts}"
    assert counts[f"/{stack.namespace}/odom"] > 40  # 20 Hz for about 6 s at rtf 1: a third of it, for a loaded machine
