"""Shared fixtures: reference data, free loopback ports, a Zenoh router and peers (real Zenoh, in-process)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from mjnav.bus import Bus, BusConfig, wait_until

REPO = Path(__file__).resolve().parent.parent
#: Environment marker every process started by this test session inherits (see ``no_process_left_behind``).
_SESSION_MARK = "MJNAV_TEST_SESSION"


def _marked_processes(mark: str) -> list[tuple[int, str]]:
    """(pid, command line) of the processes other than this one whose environment carries ``mark``."""
    needle = f"{_SESSION_MARK}={mark}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            if needle in (entry / "environ").read_bytes().split(b"\0"):
                cmd = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace").strip()
                found.append((int(entry.name), cmd))
        except OSError:  # gone meanwhile, or not ours to read
            continue
    return found


@pytest.fixture(scope="session", autouse=True)
def no_process_left_behind() -> Iterator[None]:
    """Every process a test starts inherits a session marker; at the end none may still run (they are killed and
    the session fails, naming them). Processes get a few seconds to finish a clean stop they already began."""
    mark = uuid.uuid4().hex
    os.environ[_SESSION_MARK] = mark
    yield
    wait_until(lambda: not _marked_processes(mark), 5.0, poll_s=0.2)
    left = _marked_processes(mark)
    for pid, _ in left:
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    assert not left, f"processes left behind by the tests: {left}"


def refdata_dir() -> Path | None:
    """../shared/refdata beside the project, or $MJNAV_REFDATA; None when absent."""
    env = os.environ.get("MJNAV_REFDATA")
    path = Path(env) if env else REPO.parent / "shared" / "refdata"
    return path if path.is_dir() else None


@pytest.fixture
def refdata() -> Path:
    """The reference data folder; skips the test cleanly when it is not there."""
    path = refdata_dir()
    if path is None:
        pytest.skip("reference data not found (../shared/refdata or $MJNAV_REFDATA)")
    return path


#: Ports handed out by :func:`free_port`: below Linux's ephemeral range (32768–60999), from which the OS picks the
#: local ports of outgoing connections, so no client socket takes one between the choice and the bind.
_PORTS = range(20000, 32768)
#: Ports per hand-out: the one returned and those ``--port BASE`` numbers after it for the stack's listeners
#: (mjnav.runtime.stack.port_overrides), so a port handed out later never lands on one of them.
_BLOCK = 8
# Each process walks the range from its own point (a full turn before repeating), so two test runs side by side
# do not hand out the same ports: no randomness involved.
_next_port = _PORTS.start + (os.getpid() * 7919) % len(_PORTS) // _BLOCK * _BLOCK


def _bindable(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
        return True


def stop_process(proc: subprocess.Popen[str], timeout_s: float = 20.0) -> str:
    """SIGTERM ``proc`` if it still runs, SIGKILL it after ``timeout_s``; returns what it printed."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            proc.kill()
    return proc.communicate(timeout=10)[0] or ""


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now, outside the ephemeral range, with the
    :data:`_BLOCK` - 1 ports after it free too (``--port BASE`` puts the stack's other listeners there)."""
    global _next_port
    span = len(_PORTS) // _BLOCK * _BLOCK
    for _ in range(span // _BLOCK):
        port = _next_port
        _next_port = _PORTS.start + (port + _BLOCK - _PORTS.start) % span
        if all(_bindable(port + i) for i in range(_BLOCK)):
            return port
    raise RuntimeError(f"no {_BLOCK} free TCP ports in a row in {_PORTS.start}..{_PORTS.stop - 1}")


@pytest.fixture
def port() -> int:
    """A free loopback TCP port for one test."""
    return free_port()


@pytest.fixture
def router_endpoint() -> Iterator[str]:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = Bus.open(BusConfig(mode="router", connect=(), listen=(endpoint,)))
    yield endpoint
    router.close()


@pytest.fixture
def peer(router_endpoint: str) -> Iterator[Callable[..., Bus]]:
    opened: list[Bus] = []

    def make(namespace: str = "robot0") -> Bus:
        bus = Bus.open(BusConfig(connect=(router_endpoint,)), namespace)
        opened.append(bus)
        return bus

    yield make
    for bus in opened:
        bus.close()
