"""`mjnav teleop` through a pseudo-terminal: the teleop_twist_keyboard keys become Twists on cmd_vel_teleop."""

from __future__ import annotations

import os
import pty
import subprocess
import sys
import threading
from collections.abc import Callable
from typing import Any

import pytest

from mjnav.bus import Bus, wait_until
from mjnav.commands.teleop import TeleopState
from tests.conftest import REPO


def test_keys_set_direction_and_speeds() -> None:
    state = TeleopState(0.5, 1.0)
    assert not state.press("i") and state.command() == (0.5, 0.0)
    state.press("j")
    assert state.command() == (0.0, 1.0)
    state.press("o")
    assert state.command() == (0.5, -1.0)
    assert state.press("q") and state.command() == pytest.approx((0.55, -1.1))
    state.press("x")
    assert state.command() == pytest.approx((0.495, -1.1))
    state.press("k")
    assert state.command() == (0.0, 0.0)
    state.press(",")
    state.press("?")  # any other key stops too
    assert state.command() == (0.0, 0.0)


@pytest.mark.e2e
def test_teleop_through_a_pty_publishes_the_keys(peer: Callable[..., Bus], router_endpoint: str) -> None:
    me = peer()
    got: list[tuple[float, float]] = []
    me.subscribe("cmd_vel_teleop", callback=lambda m: got.append((m.linear.x, m.angular.z)))
    master, slave = pty.openpty()
    proc = subprocess.Popen(
        [sys.executable, "-m", "mjnav", "teleop", "--connect", router_endpoint, "--rate", "20"],
        cwd=REPO, stdin=slave, stdout=slave, stderr=slave, start_new_session=True,
    )  # fmt: skip
    os.close(slave)
    screen: list[bytes] = []

    def read() -> None:
        while True:
            try:
                data = os.read(master, 1024)
            except OSError:
                return
            if not data:
                return
            screen.append(data)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert wait_until(lambda: b"Ctrl-C: quit" in b"".join(screen), 60.0), b"".join(screen)
        assert wait_until(lambda: got[-1:] == [(0.0, 0.0)], 30.0)  # idle: it holds the robot still

        def key(k: bytes, expect: Any) -> None:
            os.write(master, k)
            assert wait_until(lambda: got[-1:] == [expect], 30.0), (k, got[-5:])

        key(b"i", (0.5, 0.0))
        key(b"j", (0.0, 1.0))
        key(b"q", (0.0, 1.1))
        key(b"i", (0.55, 0.0))
        key(b"k", (0.0, 0.0))
        key(b"m", (-0.55, -1.1))
        assert wait_until(lambda: b"speed 0.55 m/s, turn 1.10 rad/s" in b"".join(screen), 10.0)
        os.write(master, b"\x03")  # Ctrl-C: a zero command, then exit 0
        assert proc.wait(30) == 0, b"".join(screen)
        assert got[-1] == (0.0, 0.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        os.close(master)
        reader.join(5)


@pytest.mark.e2e
def test_teleop_needs_a_terminal() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "mjnav", "teleop", "--connect", "tcp/127.0.0.1:1"],
        cwd=REPO, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert proc.returncode == 2 and "needs a terminal" in proc.stderr
