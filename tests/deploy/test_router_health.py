"""``mjnav router`` and ``mjnav health``: what the compose router container and every healthcheck run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading

import pytest

from mjnav.bus import Bus, BusConfig
from mjnav.msgs import from_dict
from tests.conftest import REPO, free_port

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers


def _env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if not k.startswith("MJNAV_ZENOH_")}


def _health(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "mjnav", "health", *args],
        cwd=REPO,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_router_serves_clients_and_health_reports_services() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = subprocess.Popen(
        [sys.executable, "-m", "mjnav", "router", "--listen", endpoint],
        cwd=REPO,
        env=_env(),
        text=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
    )
    stop = threading.Event()
    try:
        up = _health("--connect", endpoint, "--timeout", "20")
        assert up.returncode == 0 and "router reachable" in up.stdout, up.stderr

        with Bus.open(BusConfig(mode="client", connect=(endpoint,))) as service:
            service.declare_alive("fake")
            status = service.publisher("status", service="fake")

            def publish_status() -> None:
                steps = 0
                while not stop.wait(0.1):  # a 10 Hz status source, like a running service (1 Hz)
                    steps += 5  # a moving loop: health --status requires the step count to grow
                    fields = {"service": "fake", "state": 2, "steps": steps}
                    status.put(from_dict("mjnav_msgs/msg/ServiceStatus", fields))

            threading.Thread(target=publish_status, daemon=True).start()
            ok = _health("fake", "--status", "--connect", endpoint, "--mode", "client", "--timeout", "10")
            assert ok.returncode == 0 and "fake alive" in ok.stdout, ok.stderr
            missing = _health("fake", "ghost", "--connect", endpoint, "--timeout", "2")
            assert missing.returncode == 1 and "ghost: not alive" in missing.stderr and "fake" not in missing.stderr
    finally:
        stop.set()
        router.send_signal(signal.SIGINT)
        code = router.wait(10)
        out = router.communicate(timeout=5)[0]
    assert code == 0, out
    assert f"listening on {endpoint}" in out and "router stopped" in out


def test_health_without_a_router_is_unhealthy() -> None:
    result = _health("--connect", f"tcp/127.0.0.1:{free_port()}", "--timeout", "1")
    assert result.returncode == 1 and "no Zenoh router or peer reachable" in result.stderr
