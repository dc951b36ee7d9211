"""Service-level tests over real Zenoh on loopback with real processes: `mjnav run`, `mjnav up`, `mjnav pub`."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from mcap_ros2._dynamic import generate_dynamic

from mjnav.bus import Bus, wait_until
from mjnav.msgs import encode, from_dict, message_definition, ros
from tests.conftest import REPO, free_port

STACK = REPO / "tests" / "services" / "stack.toml"
Peer = Callable[..., Bus]


def _env() -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}
    env["PYTHONPATH"] = str(REPO)
    return env


def _mjnav(*args: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "mjnav", *args],
        cwd=REPO,
        env=_env(),
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )


@pytest.fixture
def service(router_endpoint: str) -> Iterator[subprocess.Popen[str]]:
    proc = _mjnav("run", "kinematic", "--stack", str(STACK), "--connect", router_endpoint)
    yield proc
    if proc.poll() is None:
        proc.kill()
    proc.communicate(timeout=10)


@pytest.mark.e2e
def test_service_process_decodes_rejects_and_survives(service: subprocess.Popen[str], peer: Peer) -> None:
    me = peer()
    alive: dict[str, bool] = {}
    me.watch_alive(lambda name, up: alive.__setitem__(name, up))
    assert wait_until(lambda: alive.get("kinematic") is True, 20.0), "liveliness token never appeared"

    odom = me.subscribe("odom")
    status = me.subscribe("status", service="kinematic")
    cmd = me.publisher("cmd_vel")
    assert cmd.wait_for_subscribers(10.0)
    cmd.put(ros.twist(0.5, 0.25))
    msg = odom.wait(10.0, lambda m: m.twist.twist.linear.x == 0.5)
    assert msg is not None and msg.twist.twist.angular.z == 0.25  # decoded, used, published

    key = me.key("cmd_vel")
    bad = [b"", b"\xff" * 7, encode(from_dict("geometry_msgs/msg/Twist", {"linear": {"x": math.nan}}))]
    for payload in bad:
        me.session.put(key, payload)
    report = status.wait(10.0, lambda s: s.messages_rejected >= len(bad))
    assert report is not None, "rejections never showed up in the status"
    assert report.messages_rejected == len(bad) and "cmd_vel" in report.last_error
    assert service.poll() is None  # still running
    cmd.put(ros.twist(0.2, 0.0))
    assert odom.wait(10.0, lambda m: m.twist.twist.linear.x == 0.2) is not None

    service.send_signal(signal.SIGTERM)
    assert service.wait(10.0) == 0
    assert wait_until(lambda: alive.get("kinematic") is False, 10.0), "liveliness token outlived the process"
    out = service.communicate(timeout=5)[0]
    assert "rejected message on robot0/cmd_vel" in out


@pytest.mark.e2e
def test_launcher_restarts_a_killed_service_and_stops_cleanly(peer: Peer) -> None:
    port = free_port()
    launcher = _mjnav("up", "--stack", str(STACK), "--port", str(port), "--headless")
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(launcher.stdout), daemon=True)  # type: ignore[arg-type]
    reader.start()
    try:
        from mjnav.bus import BusConfig

        me = Bus.open(BusConfig(connect=(f"tcp/127.0.0.1:{port}",)))
        try:
            status = me.subscribe("status", service="kinematic")
            first = status.wait(30.0)
            assert first is not None, "service never reported status"
            os.kill(first.pid, signal.SIGKILL)
            again = status.wait(30.0, lambda s: s.pid != first.pid)
            assert again is not None, "the launcher did not restart the killed service"
        finally:
            me.close()
        launcher.send_signal(signal.SIGINT)
        assert launcher.wait(10.0) == 0
    finally:
        if launcher.poll() is None:
            launcher.kill()
    reader.join(5.0)
    text = "".join(lines)
    assert "[kinematic]" in text and "restarting" in text and "stopped kinematic" in text


def test_a_service_compiling_its_first_step_is_not_taken_for_hung() -> None:
    """Before its first step a silent service is starting (numba compiles on first calls: tens of seconds on a
    fresh checkout), so only FIRST_STEP_TIMEOUT_S applies; once it stepped, hung_timeout_s does."""
    from mjnav.runtime.launcher import FIRST_STEP_TIMEOUT_S, Launcher, _Child
    from mjnav.runtime.stack import load_stack

    launcher = Launcher(load_stack(STACK), hung_timeout_s=2.0)
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    try:
        spec = launcher.processes[0]
        name = spec.services[0].name
        child = _Child(spec, proc=proc, last_status={name: 100.0})
        launcher._check_hung(child, proc, now=100.0 + 10.0)  # silent 10 s, no step yet: starting
        assert proc.poll() is None
        launcher._check_hung(child, proc, now=100.0 + FIRST_STEP_TIMEOUT_S + 1.0)
        assert proc.wait(10.0) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait(10.0)
    stepped = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
    try:
        child = _Child(spec, proc=stepped, last_status={name: 100.0}, stepped={name})
        launcher._check_hung(child, stepped, now=100.0 + 3.0)  # silent 3 s after stepping: hung
        assert stepped.wait(10.0) == -signal.SIGKILL
    finally:
        if stepped.poll() is None:
            stepped.kill()
        stepped.wait(10.0)


def _running(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"  # a zombie has exited (its parent has not reaped it)


@pytest.mark.e2e
def test_services_do_not_outlive_a_killed_launcher() -> None:
    port = free_port()
    launcher = _mjnav("up", "--stack", str(STACK), "--port", str(port), "--headless")
    try:
        from mjnav.bus import BusConfig

        with Bus.open(BusConfig(connect=(f"tcp/127.0.0.1:{port}",))) as me:
            first = me.subscribe("status", service="kinematic").wait(30.0)
            assert first is not None, "service never reported status"
        launcher.kill()  # SIGKILL: no chance to stop its children
        launcher.wait(10.0)
        assert wait_until(lambda: not _running(first.pid), 2.0), "the service outlived its launcher"
    finally:
        if launcher.poll() is None:
            launcher.kill()
        launcher.communicate(timeout=10)


@pytest.mark.e2e
def test_launcher_gives_up_on_a_service_that_keeps_failing() -> None:
    port = free_port()
    launcher = _mjnav("up", "--stack", str(STACK), "--port", str(port), "--set", "kinematic.fail_in_configure=true")
    lines: list[str] = []
    assert launcher.stdout is not None
    for line in launcher.stdout:  # read until the launcher reports it gave up (bounded by the test timeout)
        lines.append(line)
        if "giving up" in line:
            break
    launcher.send_signal(signal.SIGINT)
    lines += launcher.communicate(timeout=60)[0]
    out = "".join(lines)
    assert launcher.returncode == 1
    assert "configured to fail" in out
    assert out.count("restarting in") == 2 and "giving up" in out


@pytest.mark.e2e
def test_pub_puts_twists_an_outside_decoder_reads_exactly(router_endpoint: str) -> None:
    import zenoh

    from mjnav.bus import BusConfig

    decoder = generate_dynamic("geometry_msgs/msg/Twist", message_definition("geometry_msgs/msg/Twist"))[
        "geometry_msgs/msg/Twist"
    ]
    got: list[bytes] = []
    done = threading.Event()

    def on_sample(sample: zenoh.Sample) -> None:
        got.append(sample.payload.to_bytes())
        if len(got) == 5:
            done.set()

    session = zenoh.open(BusConfig(connect=(router_endpoint,)).to_zenoh())
    try:
        session.declare_subscriber("robot0/cmd_vel", on_sample)
        proc = _mjnav(
            "pub",
            "robot0/cmd_vel",
            "--connect",
            router_endpoint,
            "--count",
            "5",
            "--rate",
            "50",
            "--yaml",
            "{linear: {x: 0.25}, angular: {z: -0.5}}",
        )
        out = proc.communicate(timeout=60)[0]
        assert proc.returncode == 0, out
        assert done.wait(10.0), f"received {len(got)} of 5"
    finally:
        session.close()
    for payload in got:
        twist = decoder(payload)
        assert (twist.linear.x, twist.linear.y, twist.linear.z) == (0.25, 0.0, 0.0)
        assert (twist.angular.x, twist.angular.y, twist.angular.z) == (0.0, 0.0, -0.5)


@pytest.mark.e2e
def test_pub_rejects_bad_yaml_with_a_clear_message() -> None:
    proc = _mjnav("pub", "robot0/cmd_vel", "--yaml", "{linear: {q: 1}}", "--connect", "tcp/127.0.0.1:1")
    out = proc.communicate(timeout=60)[0]
    assert proc.returncode == 2 and "unknown field" in out
