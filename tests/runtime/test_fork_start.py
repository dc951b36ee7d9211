"""``mjnav up`` forks each service's first process from the launcher (imports and numba's set-up done once); a
restart is a fresh ``python -m mjnav run`` (the launcher runs Zenoh's threads by then, which a fork must not copy)."""

from __future__ import annotations

import os
import signal
from pathlib import Path

import pytest

from mjnav.bus import Bus, BusConfig
from tests.conftest import free_port
from tests.runtime.test_processes import STACK, _mjnav

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers


def _proc(pid: int) -> tuple[str, int, str]:
    """(comm, parent pid, command line) of a running process."""
    root = Path(f"/proc/{pid}")
    parent = int((root / "stat").read_text().rsplit(")", 1)[1].split()[1])
    cmdline = (root / "cmdline").read_bytes().replace(b"\0", b" ").decode().strip()
    return (root / "comm").read_text().strip(), parent, cmdline


def test_the_first_process_is_forked_from_the_launcher_and_a_restart_is_executed_afresh() -> None:
    port = free_port()
    launcher = _mjnav("up", "--stack", str(STACK), "--port", str(port), "--headless")
    try:
        with Bus.open(BusConfig(connect=(f"tcp/127.0.0.1:{port}",))) as me:
            status = me.subscribe("status", service="kinematic")
            first = status.wait(30.0)
            assert first is not None, "service never reported status"
            comm, parent, cmdline = _proc(first.pid)
            assert (comm, parent) == ("mjnav-kinematic", launcher.pid)
            assert " up " in f"{cmdline} "  # a fork: the launcher's command line
            os.kill(first.pid, signal.SIGKILL)
            again = status.wait(30.0, lambda s: s.pid != first.pid)
            assert again is not None, "the launcher did not restart the killed service"
            _, parent, cmdline = _proc(again.pid)
            assert parent == launcher.pid and "-m mjnav run kinematic" in cmdline
        launcher.send_signal(signal.SIGINT)
        assert launcher.wait(10.0) == 0
    finally:
        if launcher.poll() is None:
            launcher.kill()
        launcher.communicate(timeout=10)
