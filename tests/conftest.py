"""Shared fixtures: reference-data location and free loopback ports."""

from __future__ import annotations

import os
import socket
from pathlib import Path

import pytest

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
