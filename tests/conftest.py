"""Shared fixtures: reference data, free loopback ports, a Zenoh router and peers (real Zenoh, in-process)."""

from __future__ import annotations

import os
import socket
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from mjnav.bus import Bus, BusConfig

REPO = Path(__file__).resolve().parent.parent


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


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


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
