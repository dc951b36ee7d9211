"""The status heartbeat goes on while one step runs long (a numba kernel compiling), so the launcher's hang check does
not kill a working service; it stops once a step outlasts STEP_HEARTBEAT_LIMIT_S."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass

import pytest

from mjnav.bus import Bus, BusConfig, wait_until
from mjnav.runtime import Service
from mjnav.runtime import runner as runner_module
from mjnav.runtime.runner import ServiceRunner

pytestmark = pytest.mark.e2e  # processes or a live stack: see pyproject's markers

GATE = threading.Event()  # the first step blocks until the test opens it
IN_STEP = threading.Event()


@dataclass(frozen=True)
class SlowConfig:
    rate_hz: float = 10.0


class Slow(Service[SlowConfig]):
    name = "slow"
    config_class = SlowConfig
    uses_sim_time = False

    def step(self, now: float) -> None:
        IN_STEP.set()
        GATE.wait()


def _run_blocked(
    router_endpoint: str,
    peer: Callable[..., Bus],
    statuses_while_blocked: int,
    wait_s: float,
    also: Callable[[], bool] = lambda: True,
) -> tuple[int, bool]:
    """Run Slow with its first step blocked; count its status messages while blocked (waiting for
    ``statuses_while_blocked`` of them and for ``also``, at most ``wait_s`` wall seconds). Returns (count, whether
    that many came and ``also`` held)."""
    GATE.clear()
    IN_STEP.clear()
    observer = peer()
    status = observer.subscribe("status", service="slow", immediate=True)
    runner = ServiceRunner(Slow, SlowConfig(), BusConfig(connect=(router_endpoint,)), "robot0")
    thread = threading.Thread(target=runner.run)
    thread.start()
    try:
        assert IN_STEP.wait(10.0)
        seen = status.count
        came = wait_until(lambda: status.count - seen >= statuses_while_blocked and also(), wait_s)
        return status.count - seen, came
    finally:
        GATE.set()
        runner.stop_event.set()
        thread.join(10.0)
        assert not thread.is_alive()


def test_a_long_step_keeps_the_status_heartbeat_going(
    router_endpoint: str, peer: Callable[..., Bus], caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING)
    count, came = _run_blocked(
        router_endpoint, peer, 5, 15.0, also=lambda: "one step has been running for" in caplog.text
    )
    assert came, f"{count} status message(s) while the step ran; log: {caplog.text!r}"


def test_a_step_longer_than_the_limit_is_left_to_the_hang_check(
    router_endpoint: str, peer: Callable[..., Bus], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(runner_module, "STEP_HEARTBEAT_LIMIT_S", 1.5)
    count, came = _run_blocked(router_endpoint, peer, 3, 4.0)
    # At most the loop's own status from just before the step and one beat at ~1 s; none past the limit.
    assert not came and count <= 2
